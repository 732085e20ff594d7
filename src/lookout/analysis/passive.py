"""Stability analysis of the passive observer: tuning rule, SPR, KYP, frequency response.

Fossen & Strand (1999), Section 5. With diagonal gains the position/bias error
dynamics decouple into three single-input single-output loops, one per DOF, from
``eps_v_i`` (the i-th component of J(y) nu~) to ``z~_i = kappa_i y~_i - gamma b~_i``
(eqs. 33–37). Per DOF, with state ``x = [xi1~, xi2~, eta~, b~]`` and
``y~ = xi2~ + eta~``::

    xi1~' = xi2~ - k1 y~
    xi2~' = -w0^2 xi1~ - 2 zeta w0 xi2~ - k2 y~
    eta~' = eps_v - k3 y~
    b~'   = -b~ / T - (lambda / gamma) y~
    z~    = kappa y~ - gamma b~

Its transfer function is ``h(s) = hB(s) h0(s)`` with h0 of eq. (42) and
``hB(s) = kappa + lambda / (s + 1/T)`` (eq. 43, exact form; gamma cancels).
The observer is GES (Theorem 1) when each h is strictly positive real.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import numpy.typing as npt
import scipy.linalg
import xarray as xr

from lookout import _validation as check
from lookout.analysis.conditions import Condition, Inequality, Report, Verdict
from lookout.models.vessel import DOF
from lookout.observers.passive import PassiveObserver


def _gains(observer: PassiveObserver) -> dict[str, Any]:
    k = np.asarray(observer.wave_injection_gain)
    return {
        "w0": np.asarray(observer.wave_frequency),
        "zeta": np.asarray(observer.wave_damping),
        "k1": k[:3],
        "k2": k[3:],
        "k3": np.asarray(observer.position_injection_gain),
        "kappa": np.asarray(observer.velocity_injection_gain),
        "lam": np.asarray(observer.bias_injection_gain),
        "T": np.asarray(observer.bias_time_constant),
        "gamma": float(observer.lyapunov_weight),
    }


def error_loop(observer: PassiveObserver, dof: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """State-space (A, B, C) of the position/bias error loop of one DOF (eq. 37).

    Parameters
    ----------
    observer : PassiveObserver
    dof : int
        0 (surge), 1 (sway) or 2 (yaw).

    Returns
    -------
    tuple of ndarray
        A (4x4), B (4x1), C (1x4) for the state [xi1~, xi2~, eta~, b~].
    """
    g = _gains(observer)
    w0, zeta, k1, k2, k3 = (g[n][dof] for n in ("w0", "zeta", "k1", "k2", "k3"))
    kappa, lam, T, gamma = g["kappa"][dof], g["lam"][dof], g["T"][dof], g["gamma"]
    A = np.array(
        [
            [0.0, 1.0 - k1, -k1, 0.0],
            [-(w0**2), -2.0 * zeta * w0 - k2, -k2, 0.0],
            [0.0, -k3, -k3, 0.0],
            [0.0, -lam / gamma, -lam / gamma, -1.0 / T],
        ]
    )
    B = np.array([[0.0], [0.0], [1.0], [0.0]])
    C = np.array([[0.0, kappa, kappa, -gamma]])
    return A, B, C


def transfer_functions(observer: PassiveObserver, frequencies: npt.ArrayLike) -> dict[str, np.ndarray]:
    """h0(jw), hB(jw) and h(jw) per DOF, each of shape (n_frequencies, 3)."""
    w = np.asarray(frequencies, dtype=float)
    g = _gains(observer)
    s = 1j * w[:, None]
    w0, zeta, k1, k2, k3 = g["w0"], g["zeta"], g["k1"], g["k2"], g["k3"]
    # Fossen & Strand (1999), eq. (42)
    numerator = s**2 + 2.0 * zeta * w0 * s + w0**2
    denominator = s**3 + (k2 + k3 + 2.0 * zeta * w0) * s**2 + (w0**2 + 2.0 * zeta * w0 * k3 - k1 * w0**2) * s + w0**2 * k3
    h0 = numerator / denominator
    # eq. (43), exact form
    hB = g["kappa"] + g["lam"] / (s + 1.0 / g["T"])
    return {"h0": h0, "hB": hB, "h": h0 * hB}


#: The degrees of freedom that rotate (a moment per radian); the others translate.
ROTATION_DOF = ("yaw",)
#: Units of h0, hB and h, for a translation (surge, sway) and for yaw: h0 maps a
#: velocity error to a position error (s) in every DOF; hB a position error to a force
#: (N/m) or a moment (N m/rad); h = hB h0 a velocity error to a force or moment.
RESPONSE_UNITS = {
    "h0": {"translation": "s", "yaw": "s"},
    "hB": {"translation": "N/m", "yaw": "N m/rad"},
    "h": {"translation": "N s/m", "yaw": "N m s/rad"},
}


def characteristic_frequencies(observer: PassiveObserver) -> dict[str, np.ndarray]:
    """The frequencies that the tuning rule (48) orders, per DOF (rad/s).

    Returns
    -------
    dict
        ``bias_filter_frequency`` (1/T), ``bias_gain_ratio`` (lambda/kappa),
        ``wave_frequency`` (w_o) and ``cutoff_frequency`` (w_c = k3, eq. 47), each of
        shape (3,). Eq. (48) asks 1/T << lambda/kappa < w_o < w_c.
    """
    g = _gains(observer)
    return {
        "bias_filter_frequency": 1.0 / g["T"],
        "bias_gain_ratio": g["lam"] / g["kappa"],
        "wave_frequency": np.broadcast_to(g["w0"], (3,)).astype(float),
        "cutoff_frequency": np.asarray(g["k3"], dtype=float),
    }


def default_frequencies(observer: PassiveObserver, points: int = 400, decades: float = 2.0) -> np.ndarray:
    """Log-spaced grid from ``decades`` below the slowest to above the fastest
    time scale of the error loops (their poles and the frequencies of eq. 48)."""
    parts = list(characteristic_frequencies(observer).values())
    for dof in range(3):
        parts.append(np.abs(np.linalg.eigvals(error_loop(observer, dof)[0])))
    scales = np.concatenate([np.ravel(value) for value in parts])
    scales = scales[np.isfinite(scales) & (scales > 0)]
    low, high = np.log10(scales.min()) - decades, np.log10(scales.max()) + decades
    return np.logspace(low, high, points)


def frequency_response(observer: PassiveObserver, frequencies: npt.ArrayLike | None = None) -> xr.Dataset:
    """Bode data of h0, hB and h (as in Fig. 6) as a CF-style xarray Dataset.

    Parameters
    ----------
    observer : PassiveObserver
    frequencies : array_like, optional
        rad/s; default 2000 log-spaced points from two decades below the slowest
        to two above the fastest time scale of the loops
        (:func:`default_frequencies`; 1e-5 to 1.2e2 rad/s for the paper's gains).

    Returns
    -------
    xarray.Dataset
        Every variable has one unit that UDUNITS parses (``units``), as the
        simulation records do, and the Dataset carries ``Conventions`` and the
        lookout version. With dims (frequency, dof): ``h0_magnitude`` (s) and
        ``<name>_phase_deg`` (degree) for name in h0, hB, h, and per DOF the
        frequencies of the tuning rule (48) (:func:`characteristic_frequencies`,
        rad/s). hB, h and kappa have a unit per kind of DOF, so they are split: over
        ``translation`` (surge, sway) ``hB_magnitude_translation`` (N/m),
        ``h_magnitude_translation`` (N s/m) and ``velocity_injection_gain_translation``
        (N/m); for yaw ``hB_magnitude_yaw`` (N m/rad), ``h_magnitude_yaw``
        (N m s/rad) and ``velocity_injection_gain_yaw`` (N m/rad). Export with
        :func:`lookout.results.write_netcdf` or ``.to_dataframe().to_csv``.
    """
    from lookout import __version__
    from lookout.results import CONVENTIONS

    if frequencies is None:
        frequencies = default_frequencies(observer, points=2000)
    frequencies = np.asarray(frequencies, dtype=float)
    if frequencies.ndim != 1 or np.any(~np.isfinite(frequencies)) or np.any(frequencies <= 0):
        raise check.ParameterError("frequencies", "frequencies must be a 1-D array of positive finite values (rad/s)")
    responses = transfer_functions(observer, frequencies)
    translation = [index for index, dof in enumerate(DOF) if dof not in ROTATION_DOF]
    (yaw,) = [index for index, dof in enumerate(DOF) if dof in ROTATION_DOF]
    kappa = np.asarray(observer.velocity_injection_gain, dtype=float)
    data: dict[str, tuple[tuple[str, ...], Any, dict[str, str]]] = {}
    for name, value in responses.items():
        magnitude = np.abs(value)
        long_name = f"|{name}(jw)|"
        if name == "h0":
            data["h0_magnitude"] = (("frequency", "dof"), magnitude, {"units": RESPONSE_UNITS["h0"]["translation"], "long_name": long_name})
        else:
            data[f"{name}_magnitude_translation"] = (
                ("frequency", "translation"),
                magnitude[:, translation],
                {"units": RESPONSE_UNITS[name]["translation"], "long_name": f"{long_name}, surge and sway"},
            )
            data[f"{name}_magnitude_yaw"] = (
                ("frequency",),
                magnitude[:, yaw],
                {"units": RESPONSE_UNITS[name]["yaw"], "long_name": f"{long_name}, yaw"},
            )
        data[f"{name}_phase_deg"] = (("frequency", "dof"), np.degrees(np.angle(value)), {"units": "degree", "long_name": f"phase of {name}(jw)"})
    long_names = {
        "bias_filter_frequency": "1/T, bias model corner",
        "bias_gain_ratio": "lambda/kappa, zero of hB",
        "wave_frequency": "w_o, dominating wave frequency (notch)",
        "cutoff_frequency": "w_c, filter cut-off",
    }
    for name, value in characteristic_frequencies(observer).items():
        data[name] = (("dof",), value, {"units": "rad/s", "long_name": long_names[name]})
    data["velocity_injection_gain_translation"] = (
        ("translation",),
        kappa[translation],
        {"units": RESPONSE_UNITS["hB"]["translation"], "long_name": "kappa, high-frequency gain of hB, surge and sway"},
    )
    data["velocity_injection_gain_yaw"] = (
        (),
        kappa[yaw],
        {"units": RESPONSE_UNITS["hB"]["yaw"], "long_name": "kappa, high-frequency gain of hB, yaw"},
    )
    coords = {
        "frequency": ("frequency", frequencies, {"units": "rad/s", "long_name": "angular frequency"}),
        "dof": ("dof", list(DOF), {"long_name": "degree of freedom (error loop)"}),
        "translation": ("translation", [DOF[index] for index in translation], {"long_name": "translational degree of freedom"}),
    }
    attrs = {
        "Conventions": CONVENTIONS,
        "title": "frequency response of the passive observer's error loops h0, hB, h (Fossen & Strand 1999, Fig. 6)",
        "source": f"lookout {__version__}",
        "lookout_version": __version__,
    }
    return xr.Dataset(data, coords=coords, attrs=attrs)


#: Paper and equation of each check of this module.
SOURCE_48 = "Fossen & Strand (1999), eq. (48)"
SOURCE_SPR = "Fossen & Strand (1999), Theorem 1, eqs. (38)-(39); Khalil (1996), Lemma 6.1"
#: Units of lim w^2 Re h(jw) = -C A B: those of h per second squared.
LIMIT_UNITS = {"translation": "N/(m s)", "yaw": "N m/(rad s)"}


def _kind(dof: str) -> str:
    return "yaw" if dof in ROTATION_DOF else "translation"


def check_tuning_rule(observer: PassiveObserver, *, much_less_factor: float = 10.0) -> Condition:
    """Check the tuning rule of Fossen & Strand (1999), eq. (48), per DOF.

    ``1/T_i << lambda_i/kappa_i < w_oi < w_ci``, with w_c the position gain k3
    (eq. 47). "<<" is read as "smaller by at least ``much_less_factor``", i.e.
    ``much_less_factor / T <= lambda/kappa``.

    Returns
    -------
    Condition
        ``tuning_rule_48``: three inequalities per DOF (rad/s), named by the DOF.
    """
    if not much_less_factor >= 1:
        raise check.ParameterError("much_less_factor", f"much_less_factor must be >= 1; got {much_less_factor}")
    g = _gains(observer)
    inequalities = []
    much_less = (
        (f"1/T << lambda/kappa, read as {much_less_factor:g}/T <= lambda/kappa", "<=") if much_less_factor > 1 else ("1/T < lambda/kappa", "<")
    )
    for i, dof in enumerate(DOF):
        corner = g["lam"][i] / g["kappa"][i]
        chain = [
            (*much_less, much_less_factor / g["T"][i], corner),
            ("lambda/kappa < w_o", "<", corner, g["w0"][i]),
            ("w_o < w_c", "<", g["w0"][i], g["k3"][i]),
        ]
        for relation, comparison, left, right in chain:
            inequalities.append(Inequality.check(dof, relation, left, comparison, right, units="rad/s", source=SOURCE_48))
    return Condition(
        "tuning_rule_48",
        "(48)",
        "tuning rule 1/T << lambda/kappa < w_o < w_c",
        SOURCE_48,
        inequalities,
        quantities={"much_less_factor": much_less_factor},
    )


def minimum_phase_in_band(frequencies: npt.ArrayLike, phase_deg: npt.ArrayLike, cutoff_frequency: float) -> tuple[float, float]:
    """Smallest phase of h (deg) at frequencies up to 10 w_c, and where (rad/s).

    Above a decade past the cut-off, h tends to -90 deg from above (h0 ~ 1/s), and
    that asymptote would hide the SPR margin near the notch, which is what this
    reports. If no frequency lies below 10 w_c, the whole grid is used.
    """
    frequencies = np.asarray(frequencies, dtype=float)
    phase_deg = np.asarray(phase_deg, dtype=float)
    band = frequencies <= 10.0 * float(cutoff_frequency)
    if not band.any():
        band = np.ones_like(band)
    index = np.flatnonzero(band)[np.argmin(phase_deg[band])]
    return float(phase_deg[index]), float(frequencies[index])


def _certificate_inequalities(dof: str, certificate: dict) -> list[Inequality]:
    """P > 0, Q > 0 and B^T P = C of a candidate certificate: ``unverified`` when they fail."""
    check = functools.partial(Inequality.check, dof, source=SOURCE_SPR, failure=Verdict.UNVERIFIED)
    return [
        check("P > 0: lambda_min(S P S) > 0, S = diag(P)^-1/2", certificate["min_eig_P"], ">", 0.0, units=""),
        check("Q > 0: lambda_min(S Q S) > 0, S = diag(Q)^-1/2", certificate["min_eig_Q"], ">", 0.0, units=""),
        check("B^T P = C: max|B^T P - C| / max|C| < 1e-8", certificate["residual_output"], "<", 1e-8, units=""),
    ]


def check_spr(observer: PassiveObserver, *, frequencies: npt.ArrayLike | None = None) -> list[Condition]:
    """Check that each decoupled loop h_i(s) = hB_i(s) h0_i(s) is strictly positive real.

    Conditions (Khalil 1996, Lemma 6.1, for strictly proper h = C (sI - A)^-1 B):
    A Hurwitz; Re h(jw) > 0 on a dense grid (default 20,000 log-spaced points from
    three decades below the slowest to three above the fastest time scale of the
    loop, :func:`default_frequencies`, plus the notch frequency); and
    ``lim w^2 Re h(jw) = -C A B > 0``. Where these hold, a KYP certificate
    (P = P^T > 0, Q = Q^T > 0 with PA + A^T P = -Q and B^T P = C, eqs. 38–39) is
    computed by :func:`kyp_certificate` and verified; its P > 0, Q > 0 and B^T P = C
    are ``unverified`` (not ``fails``) when no certificate is found, since a failed
    search does not disprove SPR, so SPR holds only with a verified certificate. The
    condition also gives, not in the verdict, the minimum phase below 10 w_c against
    -90 deg (``min_phase_deg_in_band``): the SPR margin near the notch, which the
    overall minimum (the -90 deg asymptote) hides.

    Returns
    -------
    list of Condition
        One per DOF, in the order of :data:`~lookout.models.vessel.DOF`, keys
        ``spr_surge``, ``spr_sway``, ``spr_yaw``; each inequality is named by its DOF.
        ``quantities`` holds the numbers, ``certificate`` among them
        (:func:`kyp_certificate`, None when the frequency conditions fail).
    """
    g = _gains(observer)
    if frequencies is None:
        frequencies = default_frequencies(observer, points=20000, decades=3.0)
    conditions = []
    for i, dof in enumerate(DOF):
        w = np.sort(np.concatenate([np.asarray(frequencies, dtype=float), [g["w0"][i]]]))
        A, B, C = error_loop(observer, i)
        poles = np.linalg.eigvals(A)
        h = transfer_functions(observer, w)["h"][:, i]
        real = h.real
        j = int(np.argmin(real))
        phase = np.degrees(np.angle(h))
        in_band_phase, in_band_frequency = minimum_phase_in_band(w, phase, g["k3"][i])
        limit = float(-(C @ A @ B).item())
        kind = _kind(dof)
        check = functools.partial(Inequality.check, dof, source=SOURCE_SPR)
        frequency_domain = [
            check("A Hurwitz: max Re eig(A) < 0", float(poles.real.max()), "<", 0.0, units="1/s"),
            check("min over the grid of Re h(jw) > 0", float(real[j]), ">", 0.0, units=RESPONSE_UNITS["h"][kind]),
            check("lim w^2 Re h(jw) = -C A B > 0", limit, ">", 0.0, units=LIMIT_UNITS[kind]),
        ]
        frequency_test = all(item.holds for item in frequency_domain)
        certificate = kyp_certificate(observer, i) if frequency_test else None
        hurwitz, positive, limit_positive = frequency_domain
        if not hurwitz.holds:
            reason = f"A is not Hurwitz: its largest real part is {poles.real.max():.3g}"
        elif not positive.holds:
            reason = f"Re h(jw) = {real[j]:.3g} <= 0 at w = {w[j]:.4g} rad/s (phase {phase[j]:.2f} deg)"
        elif not limit_positive.holds:
            reason = f"lim w^2 Re h(jw) = -CAB = {limit:.3g} <= 0"
        elif certificate is None:
            raise AssertionError("the frequency-domain conditions hold, so a certificate was computed")
        elif certificate["verified"]:
            reason = "frequency-domain conditions hold and the KYP certificate is verified"
        else:
            speeds = np.abs(poles)
            if certificate["P"] is None or not np.isfinite([certificate["min_eig_P"], certificate["min_eig_Q"]]).all():
                best = "the Riccati equation of the shifted loop has no finite solution for any shift tried"
            else:
                best = (
                    f"the best candidate's smallest normalized eigenvalue is {certificate['min_eig_P'] + 0.0:.2g} for P "
                    f"and {certificate['min_eig_Q'] + 0.0:.2g} for Q, both must be > 0"
                )
            reason = (
                f"Re h(jw) > 0 on the grid, but no KYP certificate was verified in float64 ({best}; "
                f"the loop's poles span {speeds.min():.3g} to {speeds.max():.3g} rad/s, a ratio of {speeds.max() / speeds.min():.2g}): "
                "SPR is not established"
            )
        conditions.append(
            Condition(
                f"spr_{dof}",
                "Theorem 1",
                f"SPR of h = hB h0, {dof}",
                SOURCE_SPR,
                frequency_domain + ([] if certificate is None else _certificate_inequalities(dof, certificate)),
                reason,
                informational=(check("phase of h below 10 w_c > -90 deg", in_band_phase, ">", -90.0, units="deg"),),
                quantities={
                    "min_real_part": float(real[j]),
                    "min_real_part_frequency": float(w[j]),
                    "min_phase_deg": float(phase.min()),
                    "min_phase_deg_in_band": in_band_phase,
                    "min_phase_frequency_in_band": in_band_frequency,
                    "high_frequency_limit": limit,
                    "frequency_test": frequency_test,
                    "certificate": certificate,
                },
            )
        )
    return conditions


def _diagonal(values) -> str:
    return "diag(" + ", ".join(f"{v:.4g}" for v in np.ravel(values)) + ")"


def check_passive_observer(observer: PassiveObserver, *, much_less_factor: float = 10.0, frequencies: npt.ArrayLike | None = None) -> Report:
    """The tuning rule (48) (:func:`check_tuning_rule`) and SPR of each loop
    (:func:`check_spr`, Theorem 1) for ``observer``, with its gains (45)-(47)."""
    k = np.asarray(observer.wave_injection_gain)
    return Report(
        "Fossen & Strand (1999) passive observer: tuning rule (48), SPR of h = hB h0 (Theorem 1)",
        (check_tuning_rule(observer, much_less_factor=much_less_factor), *check_spr(observer, frequencies=frequencies)),
        quantities={
            "K1": observer.wave_injection_matrix(),
            "K2": observer.position_injection_matrix(),
            "velocity_injection_gain": np.asarray(observer.velocity_injection_gain),
            "bias_injection_gain": np.asarray(observer.bias_injection_gain),
            "bias_time_constant": np.asarray(observer.bias_time_constant),
            "lyapunov_weight": float(observer.lyapunov_weight),
        },
        summary=(
            f"K1 = [{_diagonal(k[:3])}; {_diagonal(k[3:])}]  (45)-(46)",
            f"K2 = {_diagonal(observer.position_injection_gain)} 1/s  (47)",
            f"Kappa = {_diagonal(observer.velocity_injection_gain)} N/m, N/m, N m/rad",
            f"Lambda = {_diagonal(observer.bias_injection_gain)} N/(m s), N/(m s), N m/(rad s)",
            f"T = {_diagonal(observer.bias_time_constant)} s",
        ),
    )


def _normalized_min_eig(matrix: np.ndarray) -> float:
    """Smallest eigenvalue of D X D with D = diag(X)^-1/2: scale-free test of X > 0."""
    diagonal = np.diag(matrix)
    if np.any(diagonal <= 0):
        return float(diagonal.min())
    scale = 1.0 / np.sqrt(diagonal)
    return float(np.linalg.eigvalsh(scale[:, None] * matrix * scale[None, :])[0])


def kyp_certificate(observer: PassiveObserver, dof: int) -> dict:
    """Compute and verify P = P^T > 0 with PA + A^T P = -Q, Q > 0, B^T P = C (eqs. 38–39).

    Method (constructive form of the strict KYP lemma, Khalil 1996, Lemma 6.3):
    states are scaled (b' = gamma b~ / kappa, output divided by kappa) so entries
    are of order one; the positive-real Riccati equation of the shifted loop
    ``C (sI - A - mu I)^-1 B + d`` with a small feedthrough d is solved; as d -> 0
    its solution meets B^T P = C up to O(sqrt(d)), and since B = e3 that row of P
    is then set to C exactly. Shift ``mu`` and ``d`` are tried from a short list
    until P > 0 and Q > 0 are verified in the original coordinates.

    Returns
    -------
    dict
        ``P``, ``Q`` (original coordinates, nested lists), ``min_eig_P`` and
        ``min_eig_Q`` (of the diagonally normalized matrices, scale-free),
        ``residual_output`` (max |B^T P - C| / max |C|) and ``verified``.
    """
    A, B, C = error_loop(observer, dof)
    kappa = float(C[0, 1])
    gamma = -float(C[0, 3])
    S = np.diag([1.0, 1.0, 1.0, gamma / kappa])
    S_inv = np.linalg.inv(S)
    As, Cs = S @ A @ S_inv, (C @ S_inv) / kappa
    margin = -np.linalg.eigvals(As).real.max()
    best = None
    for fraction in (0.5, 0.2):
        for feedthrough in (1e-6, 1e-8, 1e-10, 1e-12):
            shifted = As + fraction * margin * np.eye(4)
            try:
                X = scipy.linalg.solve_continuous_are(shifted, B, np.zeros((4, 4)), np.array([[-2.0 * feedthrough]]), s=-Cs.T)
            except (np.linalg.LinAlgError, ValueError):
                continue
            Ps = 0.5 * (X + X.T)
            Ps[2, :] = Cs[0]
            Ps[:, 2] = Cs[0]
            P = kappa * S.T @ Ps @ S
            Q = -(P @ A + A.T @ P)
            Q = 0.5 * (Q + Q.T)
            candidate = {
                "P": P.tolist(),
                "Q": Q.tolist(),
                "min_eig_P": _normalized_min_eig(P),
                "min_eig_Q": _normalized_min_eig(Q),
                "residual_output": float(np.abs(B.T @ P - C).max() / np.abs(C).max()),
            }
            candidate["verified"] = bool(candidate["min_eig_P"] > 0 and candidate["min_eig_Q"] > 0 and candidate["residual_output"] < 1e-8)
            if best is None or candidate["min_eig_Q"] > best["min_eig_Q"]:
                best = candidate
            if candidate["verified"]:
                return candidate
    if best is None:
        return {"P": None, "Q": None, "min_eig_P": float("nan"), "min_eig_Q": float("nan"), "residual_output": float("nan"), "verified": False}
    return best
