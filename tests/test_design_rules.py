"""Design rules (``design = "..."`` in a composition): Wondergem et al. (2009)'s gain
procedure for the Earth-fixed observer and the tracking controller, and Kim (2002)'s
gains verified against his (14)."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from lookout.analysis.sliding_mode import kim_2002_observer, kyp_14, sigma2
from lookout.analysis.tracking import check_wondergem_2009, propose_wondergem_2009
from lookout.models.cybership import cybership2
from lookout.models.vessel import northern_clipper
from lookout.observers import SlidingModeObserver, notch_filter_gains
from lookout.observers.passive import tuning_rule_gains
from lookout.papers.wondergem_2009.config import INITIAL_ETA, INITIAL_ETA_HAT
from lookout.scenario import registry
from lookout.scenario.composition import CompositionError, compose, simulate

# -- Wondergem et al. (2009): one proposal for the observer (6) and the scheme (23) ----------

A, B = 3.5, 1.823  # the reproduction's ellipse; its start, yaw rate and speed bounds in closed form
#: the reference's data at the start of the ellipse and its bounds (as tests/test_tracking_conditions.py)
REFERENCE = {
    "reference_position": [A, 0.0, np.pi / 2],
    "reference_velocity": [0.05, 0.0, 0.05 * A / B**2],
    "reference_yaw_rate_max": 0.2 * A / B**2,
    "reference_speed_max": 0.2 * np.hypot(1.0, A / B**2),
    "reference_acceleration_max": 0.03,
}
#: the rule's keys: Section 5's start, the estimate started at the measurement and at rest
RULE = {"design": "wondergem-2009", **REFERENCE, "start_position": list(INITIAL_ETA)}


def _wondergem_document(**observer) -> dict:
    """The reproduction's simulation case with both gains from the rule, 20 ms at 10 us:
    the procedure's L1 (about 2.5e5 1/s) needs a step below 2.8 / L1 for RK4."""
    return {
        "preset": "wondergem-2009",
        "simulation": {"duration": 0.02, "plant_step": 1e-5, "sample_period": 1e-5, "record_every": 100},
        "sensor": {"sample_period": 1e-5},
        "observer": {**RULE, **observer, "initial": {"eta": list(INITIAL_ETA), "velocity": [0.0, 0.0, 0.0]}},
        "controller": dict(RULE),
    }


def _procedure(ship, **start):
    """propose_wondergem_2009 on the same numbers, under its own names."""
    return propose_wondergem_2009(
        ship,
        eta0=INITIAL_ETA,
        nu0=(0.0, 0.0, 0.0),
        eta_hat0=start.get("eta_hat0", INITIAL_ETA),
        velocity_hat0=(0.0, 0.0, 0.0),
        reference_position0=REFERENCE["reference_position"],
        reference_velocity0=REFERENCE["reference_velocity"],
        yaw_rate_max=REFERENCE["reference_yaw_rate_max"],
        reference_speed_max=REFERENCE["reference_speed_max"],
        reference_acceleration_max=REFERENCE["reference_acceleration_max"],
    )


@pytest.mark.slow
def test_the_wondergem_rule_gives_the_procedures_gains_for_the_plants_ship_and_runs():
    composition = compose(_wondergem_document())
    observer, controller = composition.scenario.observer, composition.scenario.controller
    assert registry.kind_of(observer) == "earth-fixed" and composition.document["observer"]["design"] == "wondergem-2009"
    # the ship is the plant's (no [observer.ship] table): Cybership II of (39), D_n included
    ship = composition.scenario.plant.ship
    np.testing.assert_array_equal(observer.ship.quadratic_damping, ship.quadratic_damping)
    proposal = _procedure(cybership2())
    assert proposal.found
    np.testing.assert_array_equal(observer.position_gain, np.full(3, proposal.observer_gains[0]))
    np.testing.assert_array_equal(observer.velocity_gain, np.full(3, proposal.observer_gains[1]))
    np.testing.assert_array_equal(controller.natural_frequency, np.full(3, proposal.natural_frequency))
    np.testing.assert_array_equal(controller.damping_ratio, np.full(3, 1.0))
    # what the procedure claims: (25), Prop. 3.1 and Prop. 3.3 at its eps3, on the built gains
    report = check_wondergem_2009(
        ship,
        observer_gains=(float(observer.position_gain[0]), float(observer.velocity_gain[0])),
        natural_frequency=np.asarray(controller.natural_frequency),
        damping_ratio=np.asarray(controller.damping_ratio),
        eta0=INITIAL_ETA,
        nu0=(0.0, 0.0, 0.0),
        eta_hat0=INITIAL_ETA,
        velocity_hat0=(0.0, 0.0, 0.0),
        reference_position0=REFERENCE["reference_position"],
        reference_velocity0=REFERENCE["reference_velocity"],
        yaw_rate_max=REFERENCE["reference_yaw_rate_max"],
        reference_speed_max=REFERENCE["reference_speed_max"],
        reference_acceleration_max=REFERENCE["reference_acceleration_max"],
        epsilon3=proposal.epsilon3,
    )
    assert report.verdicts == {"controller_25": "holds", "observer_3_1": "holds", "combined_3_3": "holds"}
    assert {item.name for item in report["combined_3_3"].inequalities} == {"(27)", "(30)", "(32)"}
    trajectory = simulate(composition)
    ds = trajectory.to_xarray()
    assert ds.status.values.tolist() == ["finite"] and all(np.isfinite(np.asarray(leaf)).all() for leaf in jax.tree.leaves(trajectory.estimate))
    # started at the measurement, the estimate stays on the noise-free measured position
    assert float(np.abs(ds.position_hat - ds.position).max()) < 1e-9


def test_the_wondergem_rule_takes_the_tables_own_ship():
    """The basin's scheme: linear damping only, so other gains than for the plant's ship."""
    linear = {"kind": "cybership-ii", "quadratic_damping": [0.0, 0.0, 0.0]}
    document = _wondergem_document(ship=linear)
    document["controller"]["ship"] = linear
    composition = compose(document)
    proposal = _procedure(cybership2().linear())
    assert float(composition.scenario.observer.position_gain[0]) == proposal.observer_gains[0]
    assert float(composition.scenario.controller.natural_frequency[0]) == proposal.natural_frequency
    assert proposal.observer_gains[0] < _procedure(cybership2()).observer_gains[0]  # no D_n: smaller bounds


def test_the_wondergem_rule_refuses_a_start_the_procedure_has_no_gains_for():
    """From Section 5's printed estimate, V0 (28) grows with L1 and L2 without bound."""
    assert not _procedure(cybership2(), eta_hat0=INITIAL_ETA_HAT).found
    with pytest.raises(CompositionError) as raised:
        compose(_wondergem_document(estimate_position=list(INITIAL_ETA_HAT)))
    assert raised.value.location == ("observer", "estimate_position") and "\n" not in str(raised.value)
    # ||eta~0|| = ||(-0.2, -0.2, 1.369 rad)|| = 1.398
    assert str(raised.value).startswith(
        "observer.estimate_position: estimate_position is too far from the measurement for "
        "Wondergem et al. (2009)'s procedure: with ||eta_hat(0) - eta(0)|| = 1.4 (m and rad in one norm)"
    )
    with pytest.raises(CompositionError) as raised:
        compose(_wondergem_document(margin=1.0))
    assert str(raised.value) == "observer.margin: must be in (1, inf); got 1.0"


def test_the_observer_and_controller_rules_take_the_same_keys_the_same_way():
    """One proposal between them: the shared keys have one type and one description."""

    def schema(role, name):
        return {p.name: (p.type, p.description, p.default) for p in registry.kind(role, name).parameters("wondergem-2009")}

    observer, controller = schema("observer", "earth-fixed"), schema("controller", "tracking")
    assert set(observer) - set(controller) == {"steps_per_sample", "method", "initial_velocity"} and set(controller) <= set(observer)
    for name in set(controller) - {"ship"}:
        assert observer[name] == controller[name], name
    assert registry.kind("observer", "earth-fixed").designs == ("gains", "wondergem-2009")
    assert registry.kind("controller", "tracking").designs == ("gains", "wondergem-2009")


# -- Kim (2002): the rule's gains satisfy (14), or it says which key breaks it ----------------

KIM_WAVES = {"wave_frequency": 0.8976, "cutoff_frequency": 1.1}


def test_the_kim_rule_gains_satisfy_14_on_the_northern_clipper():
    """H1, H2 by (45)-(47), H3, H4 inside (48): (14) holds with P, Q checked here again on
    the full Sigma_2 of (9)-(10)."""
    vessel = northern_clipper()
    observer = kim_2002_observer(vessel, **KIM_WAVES, switching_gain=[10.0, 10.0, 0.01], boundary_layer=[5.0, 5.0, 0.02])
    condition = kyp_14(observer)
    assert condition.verdict == "holds"
    A, B_, C = sigma2(observer)
    P, Q = np.asarray(condition.quantities["P"]), np.asarray(condition.quantities["Q"])
    np.testing.assert_allclose(P @ A + A.T @ P, -Q, atol=1e-9 * np.abs(Q).max())
    np.testing.assert_allclose(B_.T @ P, C, atol=1e-9 * np.abs(C).max())
    for matrix in (P, Q):  # positive definite, scale-free: D X D with D = diag(X)^-1/2
        scale = 1.0 / np.sqrt(np.diag(matrix))
        assert np.linalg.eigvalsh(scale[:, None] * matrix * scale[None, :]).min() > 0
    # the composition's default rule, on the plant's own vessel and sea, gives the same gains
    composed = compose({"preset": "fossen-strand-1999", "observer": {"kind": "sliding-mode", "cutoff_frequency": 1.1}}).scenario.observer
    assert composed.gains().keys() == observer.gains().keys()
    for name, matrix in observer.gains().items():
        if name != "Kbar":
            np.testing.assert_allclose(composed.gains()[name], matrix, rtol=1e-12)


def test_a_bias_gain_above_the_wave_frequency_violates_14_and_is_refused():
    """H3/H4 = 10 1/s > w_o (Kim's printed ratio). Per DOF (14) holds only if
    h = hB h0 is SPR (Khalil, Lemma 6.3), so Re h(jw) > 0 at every w. At the frequency of
    hB's largest lag, w* = sqrt(1/T (1/T + H3/H4)) = 0.1 rad/s, hB = H4 + H3 / (jw + 1/T)
    lags 88.9 deg, and h0 of (42) lags as well below the notch: the sum is past -90 deg,
    Re h < 0, and no P, Q exist."""
    vessel = northern_clipper()
    w_o, T = KIM_WAVES["wave_frequency"], 1000.0
    kappa, _ = tuning_rule_gains(vessel.mass_matrix, np.full(3, w_o), np.full(3, T))
    lam = 10.0 * kappa
    k1, k2, k3 = notch_filter_gains(np.full(3, w_o), np.full(3, 0.1), np.full(3, 1.0), np.full(3, 1.1))
    w = np.sqrt(1.0 / T * (1.0 / T + 10.0))
    s = 1j * w
    h0 = (s**2 + 2 * 0.1 * w_o * s + w_o**2) / (
        s**3 + (k2 + k3 + 2 * 0.1 * w_o) * s**2 + (w_o**2 + 2 * 0.1 * w_o * k3 - k1 * w_o**2) * s + w_o**2 * k3
    )
    hB = kappa + lam / (s + 1.0 / T)
    assert np.degrees(np.angle(hB[0])) == pytest.approx(-88.85, abs=0.01)
    assert np.all((hB * h0).real < 0) and np.all(np.degrees(np.angle(hB * h0)) < -90.0)
    with pytest.raises(ValueError) as raised:
        kim_2002_observer(vessel, **KIM_WAVES, bias_injection_gain=lam)
    message = str(raised.value)
    assert message.startswith("bias_injection_gain must be smaller: the gains violate Kim (2002)'s (14) (surge: Re h(jw) = ")
    assert "(48) fails: lambda/kappa < w_o: 10 < 0.8976 rad/s" in message and "\n" not in message
    # the same gains as given ones: the plain rule builds them, (14) not asked
    plain = SlidingModeObserver.from_gains(vessel, **KIM_WAVES, velocity_injection_gain=kappa, bias_injection_gain=lam)
    assert kyp_14(plain).verdict == "fails"
    # in a file, at the key
    with pytest.raises(CompositionError) as raised:
        compose({"preset": "fossen-strand-1999", "observer": {"kind": "sliding-mode", **KIM_WAVES, "bias_injection_gain": lam.tolist()}})
    assert raised.value.location == ("observer", "bias_injection_gain")


def test_a_short_bias_time_constant_violates_14_and_is_refused():
    """T = 10 s: the rule's H3/H4 = sqrt(w_o / T) = 0.30 1/s sits within a factor 3 of
    1/T, so hB's lag reaches the band where h0 lags (48's 1/T << H3/H4 fails)."""
    with pytest.raises(ValueError, match=r"^bias_time_constant must be larger: the gains violate Kim \(2002\)'s \(14\) \(surge: Re h\(jw\) = -"):
        kim_2002_observer(northern_clipper(), **KIM_WAVES, bias_time_constant=10.0)
