import jax
import numpy as np
import pytest

from lookout import GaussMarkovBias, LinearWaveModel, PositionHeadingSensor, VesselPlant, VesselState, northern_clipper
from lookout.analysis import fit_decay_rate, transfer_functions
from lookout.controllers import SinusoidalInput
from lookout.observers import injection_gains_from_normalized, notch_filter_gains
from lookout.papers import fossen_strand_1999 as fs
from lookout.sim import Scenario, simulate


def test_gain_synthesis_gives_the_printed_gains_of_eq_59(paper_observer):
    K1 = np.round(paper_observer.wave_injection_matrix(), 4)
    expected_K1 = np.vstack([-2.2059 * np.eye(3), 1.6157 * np.eye(3)])
    np.testing.assert_array_equal(K1, expected_K1)
    np.testing.assert_array_equal(np.round(paper_observer.position_injection_matrix(), 4), 1.1 * np.eye(3))


def test_h0_equals_the_notch_shape_44_with_its_notch_at_the_wave_frequency(paper_observer):
    w0, zeta, zeta_n, wc = 0.8976, 0.1, 1.0, 1.1
    w = np.logspace(-3, 2, 2001)
    s = 1j * w
    desired = (s**2 + 2 * zeta * w0 * s + w0**2) / ((s**2 + 2 * zeta_n * w0 * s + w0**2) * (s + wc))
    h0 = transfer_functions(paper_observer, w)["h0"]
    for i in range(3):
        np.testing.assert_allclose(h0[:, i], desired, rtol=1e-12)
    # notch: |h0| relative to the low-pass 1/(s + wc) alone has its minimum at w0
    notch_depth = np.abs(h0[:, 0] * (s + wc))
    assert w[np.argmin(notch_depth)] == pytest.approx(w0, rel=0.01)
    assert notch_depth.min() == pytest.approx(zeta / zeta_n, rel=1e-3)


def test_normalized_gains_convert_with_bis_scales():
    kappa, lam = injection_gains_from_normalized([1.0, 1.0, 1.0], [1.0, 1.0, 1.0], mass=2.0, length=4.0, gravity=9.0)
    force, time = 18.0, np.sqrt(4.0 / 9.0)
    np.testing.assert_allclose(kappa, [force / 4.0, force / 4.0, force * 4.0])
    np.testing.assert_allclose(lam, np.array([force / 4.0, force / 4.0, force * 4.0]) / time)


@pytest.mark.parametrize(
    "args, message",
    [
        ((0.9, 0.1, 1.0, 0.8), r"cutoff_frequency must exceed wave_frequency \(w_c > w_o\)"),
        ((0.9, 0.1, 0.05, 1.1), r"notch_damping must exceed wave_damping"),
        ((-0.9, 0.1, 1.0, 1.1), "wave_frequency must be positive"),
    ],
)
def test_gain_synthesis_rejects_bad_design_parameters(args, message):
    with pytest.raises(ValueError, match=message):
        notch_filter_gains(*args)


def test_observer_rejects_non_positive_definite_mass_and_negative_time_constant(paper_observer):
    bad_mass = np.diag([5e6, -3.1e2, 3e9])
    with pytest.raises(ValueError, match=r"mass_matrix must be symmetric positive definite; its smallest eigenvalue is -310"):
        type(paper_observer)(bad_mass, np.eye(3), 0.9, 0.1, np.ones(6), 1.0, 1.0, 1.0, 1000.0)
    with pytest.raises(ValueError, match="bias_time_constant must be positive"):
        type(paper_observer)(np.eye(3), np.eye(3), 0.9, 0.1, np.ones(6), 1.0, 1.0, 1.0, [1000.0, -5.0, 1000.0])
    with pytest.raises(ValueError, match="hold must be one of 'measurement', 'innovation'; got 'output'"):
        type(paper_observer)(np.eye(3), np.eye(3), 0.9, 0.1, np.ones(6), 1.0, 1.0, 1.0, 1000.0, hold="output")
    with pytest.raises(ValueError, match="mass_matrix must be symmetric"):
        northern_clipper().__class__(np.array([[1.0, 2.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), np.eye(3))


def _noise_free_run(paper_observer, duration):
    """Theorem 1 setting: n = w = d = 0, bias following (16), continuous observer."""
    plant = VesselPlant(northern_clipper(), GaussMarkovBias(1000.0, 0.0), LinearWaveModel(0.8976, 0.1, 0.0))
    truth = VesselState.build(eta=[10.0, -5.0, 0.2], nu=[0.2, -0.1, 0.002], bias=[2e4, -1e4, 2e5], wave_state=[1.0, -1.0, 0.01, 0.5, -0.5, 0.005])
    scenario = Scenario(
        plant,
        PositionHeadingSensor(0.0, 1.0),
        paper_observer,
        SinusoidalInput(fs.INPUT_AMPLITUDE, fs.INPUT_FREQUENCIES),
        truth,
        paper_observer.guess(),
        plant_step=0.1,
        sample_period=1.0,
        duration=duration,
        observer_mode="continuous",
    )
    return simulate(scenario, jax.random.key(0))


def test_noise_free_estimation_errors_decay_exponentially_below_1e_minus_6(paper_observer):
    """Fossen & Strand (1999), Theorem 1 (GES), checked per state group.

    Each group's error is normalized per component by its initial value, so
    metres, newtons and radians weigh alike; "exponential" means a log-linear fit
    between 1e-2 and 1e-8 of the initial size with R^2 > 0.95.
    """
    trajectory = _noise_free_run(paper_observer, duration=6000.0)
    time = np.asarray(trajectory.time)
    rates = {}
    errors = fs.paper_view(trajectory.to_xarray()).isel(run=0)
    for name in ("eta", "nu", "bias", "wave"):
        error = (errors[name] - errors[f"{name}_hat"]).values
        if name in ("eta", "wave"):
            error[:, 2] = np.angle(np.exp(1j * error[:, 2]))
        magnitude = np.linalg.norm(error / np.abs(error[0]), axis=1)
        relative = magnitude / magnitude[0]
        assert relative[-1] < 1e-6, f"{name} error only fell to {relative[-1]:.2e} of its initial size"
        fit = fit_decay_rate(time, magnitude, upper=1e-2, lower=1e-8)
        assert fit["rate"] > 0 and fit["r_squared"] > 0.95, fit
        rates[name] = round(fit["rate"], 5)
    print("fitted decay rates (1/s):", rates)
