"""IMU grades as data: the white noise and the biases of a consumer, an industrial, a
tactical and a navigation-grade IMU, each figure in its source's units and converted to
SI here (:class:`ImuGrade`, :data:`GRADES`). An
:class:`~lookout.sensing.motion.InertialUnit` built with ``grade = "tactical"`` takes its
white noise per sample and its biases from them.

**Two biases.** An inertial sensor's bias has a static part, the turn-on bias (bias
repeatability: a constant through one run that differs from run to run), and a dynamic
part, the in-run bias instability, which wanders through a run (Groves (2013),
Principles of GNSS, Inertial, and Multisensor Integrated Navigation Systems, 2nd ed.,
Section 4.4.1; IEEE Std 952-1997's bias repeatability and bias instability). An aided
observer learns the static part while its references last; the dynamic part is what
it cannot learn ahead, and what its dead reckoning drifts on. Each grade has both: the
one its source gives, and the other from Groves's rule of thumb that "the dynamic bias
is typically about 10 % of the static bias" (Section 4.4.1), marked below where used.

Sources, one a grade (public datasheet-style figures, 1 sigma):

* ``consumer``: the commercial (automotive) column of El-Sheimy & Youssef (2020),
  "Inertial sensors technologies for navigation applications: state of the art and
  future trends", Satellite Navigation 1:2, Table 1: gyro drift 0.1 deg/s, gyro random
  walk "several" deg/sqrt(h) (taken as 3 deg/sqrt(h)), accelerometer bias 100-1000
  micro-g (taken at its top, 1 mg), taken as turn-on biases. The table gives no
  accelerometer noise: 400 micro-g/sqrt(Hz) is the InvenSense MPU-6000/MPU-6050's
  (Product Specification PS-MPU-6000A-00 rev. 3.4, section 6.2), a consumer MEMS part.
  Representative of the grade, not one device's: a part of the grade may be better or
  worse.
* ``industrial``: the Xsens MTi 1-series datasheet (MTi-1): gyro in-run bias stability
  10 deg/h, gyro noise density 0.007 deg/s/sqrt(Hz), accelerometer in-run bias stability
  0.03 mg, accelerometer noise density 120 micro-g/sqrt(Hz). In-run figures (the floor
  of an Allan deviation); the turn-on biases ten times them (Groves's rule).
* ``tactical``: the Honeywell HG1700 datasheet (its 1 deg/h variants): accelerometer
  bias 1 mg, velocity random walk 0.065 ft/s/sqrt(h), gyro bias 1 deg/h, angle random
  walk 0.125 deg/sqrt(h). The sheet's biases are over a run (turn-on); the in-run
  instabilities a tenth of them (Groves's rule).
* ``navigation``: the Honeywell HG9900 brochure (N61-1638-000-000): accelerometer bias
  25 micro-g, gyro bias 0.0035 deg/h, angle random walk 0.002 deg/sqrt(h), taken as
  turn-on biases, the in-run instabilities a tenth of them (Groves's rule). The brochure
  gives no velocity random walk: 0.02 ft/s/sqrt(h) (10 micro-g/sqrt(Hz)) is a class
  figure of ours, not Honeywell's, a third of the HG1700's.

The sources do not all define their figures alike (an MEMS datasheet's bias
instability is in-run, a Honeywell sheet's bias over a run, and El-Sheimy & Youssef's
Table 1 puts a commercial accelerometer's bias, 100-1000 micro-g, below a tactical one's,
1-5 mg), so the grades' order is not the same in every figure: the tactical
accelerometer's in-run instability (0.1 mg) is the consumer one's, above the industrial
one's (0.03 mg). The turn-on bias is a constant drawn at the first sample; the in-run
bias a first-order Gauss-Markov process
(:class:`~lookout.sensing.instrument.GaussMarkovError`) of that stationary spread.

**Correlation time: 3600 s for every grade.** None of the sources states one (Groves
writes that the dynamic bias varies "over periods of order a minute"). Bias instability
describes how a bias wanders over the long averaging times of an Allan deviation's
floor (minutes to hours); one hour keeps the in-run bias of a DP run (20 min to an hour)
correlated through it, and one value for all grades lets a grade change the sizes only.
Give ``bias_time_constant`` for another.

Conversions: 1 deg/h = pi/180/3600 rad/s; 1 deg/sqrt(h) = pi/180/60 rad/sqrt(s);
1 mg = 9.80665e-3 m/s2 (standard gravity); 1 ft/s/sqrt(h) = 0.3048/60 m/s/sqrt(s); a
density in unit/sqrt(Hz) is the same number in unit*sqrt(s) (rad/s/sqrt(Hz) is
rad/sqrt(s)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from lookout import _validation as check

#: Standard gravity (m/s2): what 1 g is in a datasheet's mg and micro-g.
STANDARD_GRAVITY = 9.80665


def degrees_per_hour(value: float) -> float:
    """deg/h in rad/s."""
    return value * math.pi / 180.0 / 3600.0


def degrees_per_second(value: float) -> float:
    """deg/s (or deg/s/sqrt(Hz)) in rad/s (rad/s/sqrt(Hz))."""
    return value * math.pi / 180.0


def degrees_per_root_hour(value: float) -> float:
    """deg/sqrt(h) in rad/sqrt(s) (= rad/s/sqrt(Hz))."""
    return value * math.pi / 180.0 / 60.0


def milli_g(value: float) -> float:
    """mg in m/s2."""
    return value * 1e-3 * STANDARD_GRAVITY


def micro_g(value: float) -> float:
    """micro-g (or micro-g/sqrt(Hz)) in m/s2 (m/s2/sqrt(Hz))."""
    return value * 1e-6 * STANDARD_GRAVITY


def feet_per_second_per_root_hour(value: float) -> float:
    """ft/s/sqrt(h) in m/s/sqrt(s) (= m/s2/sqrt(Hz))."""
    return value * 0.3048 / 60.0


@dataclass(frozen=True)
class ImuGrade:
    """One grade of IMU, in SI units.

    Attributes
    ----------
    name : str
        The grade's name (``"tactical"``).
    accelerometer_noise_density : float
        Velocity random walk, the accelerometers' white-noise density (m/s2/sqrt(Hz)).
    gyro_noise_density : float
        Angle random walk, the rate gyro's white-noise density (rad/s/sqrt(Hz)).
    accelerometer_bias_instability : float
        In-run bias instability: the stationary standard deviation of each
        accelerometer's drifting bias (m/s2).
    gyro_bias_instability : float
        In-run bias instability: the stationary standard deviation of the rate gyro's
        drifting bias (rad/s).
    accelerometer_turn_on_bias : float
        Turn-on bias (bias repeatability): the standard deviation of each
        accelerometer's bias constant through a run (m/s2).
    gyro_turn_on_bias : float
        Turn-on bias of the rate gyro (rad/s).
    bias_time_constant : float
        Correlation time of the drifting biases (s).
    source : str
        Where the figures come from, in their own units.
    """

    name: str
    accelerometer_noise_density: float
    gyro_noise_density: float
    accelerometer_bias_instability: float
    gyro_bias_instability: float
    accelerometer_turn_on_bias: float
    gyro_turn_on_bias: float
    bias_time_constant: float
    source: str

    def accelerometer_std(self, sample_period: float) -> float:
        """Standard deviation of each accelerometer's white noise per sample (m/s2):
        the density over sqrt(sample_period), a sample averaging over its period."""
        return self.accelerometer_noise_density / math.sqrt(sample_period)

    def gyro_std(self, sample_period: float) -> float:
        """Standard deviation of the rate gyro's white noise per sample (rad/s): the
        density over sqrt(sample_period), a sample averaging over its period."""
        return self.gyro_noise_density / math.sqrt(sample_period)


#: The correlation time of every grade's drifting biases (s): see the module's text.
BIAS_TIME_CONSTANT = 3600.0
#: Groves (2013), Section 4.4.1: "the dynamic bias is typically about 10 % of the static
#: bias": the in-run bias instability over the turn-on bias, where a source gives one.
DYNAMIC_TO_STATIC = 0.1

GRADES: dict[str, ImuGrade] = {
    "consumer": ImuGrade(
        "consumer",
        accelerometer_noise_density=micro_g(400.0),  # 400 micro-g/sqrt(Hz), MPU-6050
        gyro_noise_density=degrees_per_root_hour(3.0),  # "several" deg/sqrt(h), Table 1
        accelerometer_bias_instability=DYNAMIC_TO_STATIC * micro_g(1000.0),  # Groves's rule
        gyro_bias_instability=DYNAMIC_TO_STATIC * degrees_per_second(0.1),  # Groves's rule
        accelerometer_turn_on_bias=micro_g(1000.0),  # 100-1000 micro-g, Table 1: the top
        gyro_turn_on_bias=degrees_per_second(0.1),  # 0.1 deg/s, Table 1
        bias_time_constant=BIAS_TIME_CONSTANT,
        source="El-Sheimy & Youssef (2020), Table 1, commercial grade; accelerometer noise of the MPU-6050",
    ),
    "industrial": ImuGrade(
        "industrial",
        accelerometer_noise_density=micro_g(120.0),  # 120 micro-g/sqrt(Hz)
        gyro_noise_density=degrees_per_second(0.007),  # 0.007 deg/s/sqrt(Hz)
        accelerometer_bias_instability=milli_g(0.03),  # 0.03 mg, in-run
        gyro_bias_instability=degrees_per_hour(10.0),  # 10 deg/h, in-run
        accelerometer_turn_on_bias=milli_g(0.03) / DYNAMIC_TO_STATIC,  # Groves's rule
        gyro_turn_on_bias=degrees_per_hour(10.0) / DYNAMIC_TO_STATIC,  # Groves's rule
        bias_time_constant=BIAS_TIME_CONSTANT,
        source="Xsens MTi 1-series datasheet (MTi-1)",
    ),
    "tactical": ImuGrade(
        "tactical",
        accelerometer_noise_density=feet_per_second_per_root_hour(0.065),  # 0.065 ft/s/sqrt(h)
        gyro_noise_density=degrees_per_root_hour(0.125),  # 0.125 deg/sqrt(h)
        accelerometer_bias_instability=DYNAMIC_TO_STATIC * milli_g(1.0),  # Groves's rule
        gyro_bias_instability=DYNAMIC_TO_STATIC * degrees_per_hour(1.0),  # Groves's rule
        accelerometer_turn_on_bias=milli_g(1.0),  # 1 mg
        gyro_turn_on_bias=degrees_per_hour(1.0),  # 1 deg/h
        bias_time_constant=BIAS_TIME_CONSTANT,
        source="Honeywell HG1700 datasheet",
    ),
    "navigation": ImuGrade(
        "navigation",
        accelerometer_noise_density=feet_per_second_per_root_hour(0.02),  # 0.02 ft/s/sqrt(h): a class figure
        gyro_noise_density=degrees_per_root_hour(0.002),  # 0.002 deg/sqrt(h)
        accelerometer_bias_instability=DYNAMIC_TO_STATIC * micro_g(25.0),  # Groves's rule
        gyro_bias_instability=DYNAMIC_TO_STATIC * degrees_per_hour(0.0035),  # Groves's rule
        accelerometer_turn_on_bias=micro_g(25.0),  # 25 micro-g
        gyro_turn_on_bias=degrees_per_hour(0.0035),  # 0.0035 deg/h
        bias_time_constant=BIAS_TIME_CONSTANT,
        source="Honeywell HG9900 brochure; velocity random walk a navigation-grade class figure",
    ),
}

#: The grades' names, best last.
GRADE_NAMES: tuple[str, ...] = tuple(GRADES)


def imu_grade(name: str) -> ImuGrade:
    """The grade called ``name``; a :class:`~lookout._validation.ParameterError` at
    ``grade`` for another."""
    if not isinstance(name, str) or name not in GRADES:
        raise check.ParameterError("grade", f"grade must be one of {', '.join(GRADE_NAMES)}; got {name!r}")
    return GRADES[name]


__all__ = ["GRADES", "GRADE_NAMES", "ImuGrade", "imu_grade"]
