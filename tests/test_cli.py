import json
import os
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr

import lookout._commandline
import lookout.cli
from lookout.cli import main
from lookout.papers import fossen_strand_1999
from lookout.papers._report import json_safe, mean_and_spread

REPRODUCE = ["reproduce", "fossen-strand-1999"]
DESIGN = ["design", "passive-observer"]


def _tree(folder):
    return sorted(str(path.relative_to(folder)) for path in folder.rglob("*"))


def test_list(capsys):
    assert main(["list"]) == 0
    assert "fossen-strand-1999" in capsys.readouterr().out


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"lookout {lookout.__version__}"


@pytest.mark.parametrize("argv", [[], ["design"]])
def test_no_arguments_print_help_without_an_error_line(argv, capsys):
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out.startswith("Usage: lookout") and "Commands:" in captured.out
    assert captured.err == ""


@pytest.mark.parametrize("argv", [["--help"], ["reproduce", "--help"], ["design", "passive-observer", "--help"]])
def test_help_fits_80_columns_without_cut_names_or_bool_metavars(argv, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "<bool>" not in text and "…" not in text
    assert max(len(line) for line in text.splitlines()) <= 80
    if argv[0] == "reproduce":
        for option in ("--seed INT", "--runs N", "--duration SECONDS", "--out FOLDER"):
            assert option in text
        assert text.count("[default:") >= 4
    if argv[0] == "design":
        assert "--normalized " in text and "--no-normalized" not in text
        assert "Exit code 0" in text


SPR = ("spr_surge", "spr_sway", "spr_yaw")
TUNING_RULE = "(48) tuning rule 1/T << lambda/kappa < w_o < w_c [Fossen & Strand (1999), eq. (48)]"


def _spr_header(dof: str) -> str:
    return f"Theorem 1 SPR of h = hB h0, {dof} [Fossen & Strand (1999), Theorem 1, eqs. (38)-(39); Khalil (1996), Lemma 6.1]"


def test_design_json_reports_gains_verdicts_and_frequency_response(capsys, tmp_path):
    bode = tmp_path / "bode.png"
    code = main([*DESIGN, "--wave-period", "7.0", "--frequency", "0.8976", "--frequency", "0.1", "--bode", str(bode), "--json"])
    assert code == 0
    result = json.loads(capsys.readouterr().out)
    assert result["design"] == "passive-observer" and result["holds"] and result["verdict"] == "holds"
    assert result["verdicts"] == {"tuning_rule_48": "holds", **{key: "holds" for key in SPR}}
    K1 = result["quantities"]["K1"]
    assert round(K1[0][0], 4) == -2.2059 and round(K1[3][0], 4) == 1.6157
    assert result["spr_surge"]["quantities"]["certificate"]["verified"]
    first = result["quantities"]["frequency_response"][0]
    assert set(first) == {"frequency", "magnitude", "phase_deg"}
    assert result["inputs"]["bode"] == str(bode) and bode.stat().st_size > 0
    assert f"Bode plot written to {bode}" in result["notes"]


def test_design_text_output(capsys):
    assert main([*DESIGN, "--wave-frequency", "0.8976", "--frequency", "0.5"]) == 0
    out = capsys.readouterr().out
    assert f"{TUNING_RULE}: holds" in out
    assert "    surge: lambda/kappa < w_o: 0.03588 < 0.8976 rad/s: holds, margin 0.862, factor 25" in out
    assert f"{_spr_header('yaw')}: holds" in out and "KYP certificate is verified" in out and "note: |h0(j0.5)|" in out
    assert "K1 = [diag(-2.206, -2.206, -2.206); diag(1.616, 1.616, 1.616)]" in out
    assert "cut-off w_c = 1.1 rad/s" in out  # the paper's ratio, followed by the default
    assert out.endswith("verdict: passes (exit code 0)\n")


def test_design_default_cutoff_follows_the_wave_frequency(capsys):
    assert main([*DESIGN, "--wave-period", "5", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["inputs"]["cutoff_frequency"] == pytest.approx(1.1 / 0.8976 * 2 * np.pi / 5, rel=1e-12)
    assert result["holds"]
    assert main([*DESIGN, "--wave-period", "5", "--cutoff-frequency", "2.5", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["inputs"]["cutoff_frequency"] == 2.5
    # slower waves keep the paper's w_c = 1.1 rad/s (K2 independent of w_o, Remark 2), and pass
    assert main([*DESIGN, "--wave-period", "10", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["inputs"]["cutoff_frequency"] == 1.1 and result["holds"]
    # scaling w_c with w_o there would keep (48) but break SPR: the rule is not sufficient
    assert main([*DESIGN, "--wave-period", "10", "--cutoff-frequency", str(1.1 / 0.8976 * 2 * np.pi / 10), "--json"]) == 1
    result = json.loads(capsys.readouterr().out)
    assert result["verdicts"] == {"tuning_rule_48": "holds", **{key: "fails" for key in SPR}} and result["verdict"] == "fails"


def test_design_failing_verdict_exits_1_and_still_reports(capsys):
    assert main([*DESIGN, "--wave-period", "200"]) == 1
    out = capsys.readouterr().out
    assert f"{TUNING_RULE}: fails" in out and f"{_spr_header('surge')}: fails" in out
    assert out.endswith("verdict: FAILS (exit code 1)\n")
    assert main([*DESIGN, "--wave-period", "200", "--json"]) == 1
    result = json.loads(capsys.readouterr().out)
    assert not result["holds"] and result["verdict"] == "fails" and result["spr_surge"]["verdict"] == "fails"


def test_spr_holds_never_appears_without_a_certificate(capsys):
    """At w_c = 1e6 the loop passes the frequency test but no certificate is found:
    the verdict says SPR is not established, why, and the design does not pass."""
    assert main([*DESIGN, "--wave-frequency", "0.8976", "--cutoff-frequency", "1e6", "--json"]) == 1
    result = json.loads(capsys.readouterr().out)
    assert result["verdicts"] == {"tuning_rule_48": "holds", **{key: "unverified" for key in SPR}}
    assert result["verdict"] == "unverified" and not result["holds"]
    for key in SPR:
        loop = result[key]
        assert loop["quantities"]["frequency_test"] and not loop["quantities"]["certificate"]["verified"]
        assert "no KYP certificate was verified" in loop["reason"] and "poles span" in loop["reason"]
    assert main([*DESIGN, "--wave-frequency", "0.8976", "--cutoff-frequency", "1e6"]) == 1
    out = capsys.readouterr().out
    assert f"{_spr_header('surge')}: unverified" in out and f"{_spr_header('surge')}: holds" not in out
    assert out.endswith("verdict: NOT ESTABLISHED (exit code 1)\n")


def test_design_prints_small_numbers_with_significant_digits(capsys):
    assert main([*DESIGN, "--wave-frequency", "1e-9"]) == 1
    out = capsys.readouterr().out
    assert "w_o = 1e-09 rad/s" in out and "0.0000" not in out


def test_design_normalized_gains_convert_like_the_default(capsys):
    assert main([*DESIGN, "--wave-frequency", "0.8976", "--json"]) == 0
    default = json.loads(capsys.readouterr().out)
    argv = [*DESIGN, "--wave-frequency", "0.8976", "--normalized", "--velocity-gain", "0.1,0.1,0.01", "--bias-gain", "0.01,0.01,0.001", "--json"]
    assert main(argv) == 0
    normalized = json.loads(capsys.readouterr().out)
    assert normalized["inputs"]["velocity_injection_gain"] == pytest.approx(default["inputs"]["velocity_injection_gain"], rel=1e-12)
    assert normalized["inputs"]["bias_injection_gain"] == pytest.approx(default["inputs"]["bias_injection_gain"], rel=1e-12)
    assert main([*DESIGN, "--wave-frequency", "0.8976", "--velocity-gain", "5e4", "--bias-gain", "2e3", "--json"]) == 0
    si = json.loads(capsys.readouterr().out)
    assert si["inputs"]["velocity_injection_gain"] == [5e4, 5e4, 5e4] and si["inputs"]["bias_injection_gain"] == [2e3, 2e3, 2e3]


# Every bad input: exit code 2, one line on stderr naming the option, no traceback, nothing written.
BAD_INPUTS = [
    # (argv with {tmp} for the test's folder, the option named, a fragment of the message)
    ([*REPRODUCE, "--out", "{tmp}/a-file/out"], "--out", "a-file is a file, not a folder (on the way to --out"),
    ([*REPRODUCE, "--out", "{tmp}/a-file"], "--out", "is an existing file"),
    ([*REPRODUCE, "--out", ""], "--out", "empty path"),
    ([*DESIGN, "--wave-period", "7", "--bode", "{tmp}/a-file/bode.png"], "--bode", "a-file is a file, not a folder"),
    ([*DESIGN, "--wave-period", "7", "--bode", "{tmp}"], "--bode", "must name a file, not the folder"),
    ([*DESIGN, "--wave-period", "7", "--bode", "{tmp}/bode.xyz"], "--bode", "must end in a format matplotlib writes"),
    ([*DESIGN, "--wave-period", "7", "--bode", "{tmp}/bode"], "--bode", "must end in a format matplotlib writes"),
    ([*REPRODUCE, "--seed", "99999999999999999999"], "--seed", "must be an integer from 0 to 9223372036854775807"),
    ([*REPRODUCE, "--seed", "9223372036854775807", "--runs", "2"], "--seed", "from 0 to 9223372036854775806"),
    ([*REPRODUCE, "--seed", "-1"], "--seed", "must be an integer from 0"),
    ([*REPRODUCE, "--runs", "1000000", "--duration", "3000"], "--runs", "use fewer --runs or a shorter --duration"),
    ([*REPRODUCE, "--runs", "0"], "--runs", "must be a positive integer"),
    ([*REPRODUCE, "--duration", "nan"], "--duration", "must be a finite positive number; got nan"),
    ([*REPRODUCE, "--duration", "inf"], "--duration", "must be a finite positive number; got inf"),
    ([*REPRODUCE, "--duration", "-5"], "--duration", "must be a finite positive number; got -5"),
    ([*REPRODUCE, "--duration", "10.05"], "--duration", "whole multiple of the observer's sample period (0.1 s); got 10.05 s"),
    ([*REPRODUCE, "--duration", "0.1"], "--duration", "must be at least 10 s (10 position fixes"),
    ([*REPRODUCE, "--record-interval", "1"], "--record-interval", "No such option"),
    (["reproduce", "nope"], "nope", "unknown reproduction 'nope'; available: fossen-strand-1999"),
    ([*DESIGN, "--wave-frequency", "abc"], "--wave-frequency", "Invalid value for '--wave-frequency'"),
    ([*DESIGN, "--wave-frequency", "0"], "--wave-frequency", "must be a finite positive number; got 0"),
    ([*DESIGN, "--wave-period", "nan"], "--wave-period", "must be a finite positive number; got nan"),
    ([*DESIGN], "--wave-frequency", "give exactly one of --wave-frequency and --wave-period"),
    ([*DESIGN, "--wave-frequency", "1", "--wave-period", "6"], "--wave-period", "give exactly one"),
    (
        [*DESIGN, "--wave-period", "5", "--cutoff-frequency", "1.1"],
        "--cutoff-frequency",
        "must exceed the wave frequency w_o = 1.257 rad/s (from --wave-period 5); got 1.1: raise it, or leave it out for max(1.1, 1.2255 w_o)",
    ),
    ([*DESIGN, "--wave-frequency", "0.9", "--velocity-gain", "-1"], "--velocity-gain", "got -1"),
    ([*DESIGN, "--wave-frequency", "0.9", "--velocity-gain", "1,2"], "--velocity-gain", "three separated by commas"),
    ([*DESIGN, "--wave-frequency", "0.9", "--bias-gain", "x"], "--bias-gain", "got x"),
    ([*DESIGN, "--wave-frequency", "0.9", "--bias-time-constant", "-3"], "--bias-time-constant", "got -3"),
    ([*DESIGN, "--wave-frequency", "0.9", "--wave-damping", "0"], "--wave-damping", "finite positive"),
    ([*DESIGN, "--wave-frequency", "0.9", "--notch-damping", "0.05"], "--notch-damping", "must exceed --wave-damping (0.1); got 0.05"),
    ([*DESIGN, "--wave-frequency", "0.9", "--wave-damping", "2"], "--wave-damping", "must be below --notch-damping (1, its default); got 2"),
    ([*DESIGN, "--wave-period", "7", "--lyapunov-weight", "1e300"], "--lyapunov-weight", "outside 1e-12 to 1e+12"),
    ([*DESIGN, "--wave-period", "7", "--normalized", "--velocity-gain", "1e300"], "--velocity-gain", "lambda/kappa = 3.59e-303 rad/s is outside"),
    ([*DESIGN, "--wave-period", "7", "--velocity-gain", "1e-300"], "--velocity-gain", "is outside 1e-12 to 1e+12 rad/s"),
    ([*DESIGN, "--wave-period", "7", "--frequency", "1e300"], "--frequency", "w = 1e+300 rad/s is outside"),
    ([*DESIGN, "--wave-period", "1e20"], "--wave-period", "w_o = 6.28e-20 rad/s is outside"),
    ([*DESIGN, "--wave-frequency", "0.9", "--lyapunov-weight", "-1"], "--lyapunov-weight", "finite positive"),
    ([*DESIGN, "--wave-frequency", "0.9", "--frequency", "-2"], "--frequency", "finite positive"),
    ([*DESIGN, "--wave-frequency", "0.9", "--bogus"], "--bogus", "No such option: --bogus"),
]


@pytest.mark.parametrize("argv, option, fragment", BAD_INPUTS, ids=[" ".join(case[0][1:]) for case in BAD_INPUTS])
def test_bad_input_is_one_line_naming_the_option_with_exit_code_2_and_nothing_written(argv, option, fragment, capsys, tmp_path, monkeypatch):
    (tmp_path / "a-file").write_text("not a folder")
    monkeypatch.chdir(tmp_path)
    before = _tree(tmp_path)
    assert main([arg.format(tmp=tmp_path) for arg in argv]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), captured.err
    assert option in lines[0] and fragment in lines[0], lines[0]
    assert "Traceback" not in captured.err + captured.out
    for python_name in ("velocity_injection_gain", "bias_injection_gain", "cutoff_frequency", "validation error", "pydantic", "Format '"):
        assert python_name not in lines[0]
    assert "[-1" not in lines[0]  # a scalar is echoed as typed, not tripled
    assert _tree(tmp_path) == before
    assert "Warning" not in captured.err  # no numpy warnings before the line


def test_output_folder_on_a_file_system_that_refuses_writes(capsys, tmp_path, monkeypatch):
    """Permission bits can say yes (root) where the file system says no (/proc, read-only
    mounts): the folder is tried with a temporary file before anything is simulated."""
    import tempfile

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Read-only file system")

    monkeypatch.setattr(tempfile, "TemporaryFile", refuse)
    monkeypatch.chdir(tmp_path)
    assert main([*REPRODUCE, "--out", "out", "--duration", "10"]) == 2
    assert main([*DESIGN, "--wave-period", "7", "--bode", "b.png"]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert errors == [
        f"error: --out: cannot write into the folder {tmp_path}: Read-only file system",
        f"error: --bode: cannot write into the folder {tmp_path}: Read-only file system",
    ]
    assert list(tmp_path.iterdir()) == []


def test_design_json_is_strict_json():
    """Non-finite numbers print as null, never as NaN or Infinity, which JSON parsers reject."""
    assert json_safe({"a": [1.0, float("nan")], "b": (float("inf"), "x"), "c": {"d": -float("inf"), "e": 2}}) == {
        "a": [1.0, None],
        "b": [None, "x"],
        "c": {"d": None, "e": 2},
    }


def test_output_folder_that_is_not_writable(capsys, tmp_path, monkeypatch):
    """os.access stands in for a read-only folder (the suite may run as root, who may write anywhere)."""
    locked = tmp_path / "locked"
    locked.mkdir()
    real_access = os.access
    monkeypatch.setattr(lookout._commandline.os, "access", lambda path, mode: False if str(path) == str(locked) else real_access(path, mode))
    assert main([*REPRODUCE, "--out", str(locked / "out"), "--duration", "10"]) == 2
    assert main([*DESIGN, "--wave-period", "7", "--bode", str(locked / "b.png")]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert errors == [f"error: --out: the folder {locked} is not writable", f"error: --bode: the folder {locked} is not writable"]
    assert list(locked.iterdir()) == []


def test_memory_estimate_refuses_before_simulating(capsys, monkeypatch):
    monkeypatch.setattr(lookout._commandline, "available_memory", lambda: 8_000_000_000)
    assert main([*REPRODUCE, "--duration", "1e7"]) == 2
    line = capsys.readouterr().err.strip()
    # 1e8 samples x (296 B of records, x4 while writing, + 32 B per record): 122 GB
    assert line == (
        "error: --runs 1 over --duration 1e+07 would need about 122 GB of memory (1 run(s) x 100000000 records x 296 B, "
        "x4 while writing results), and 8 GB are available: use a shorter --duration"
    )


def test_entry_point_exit_code_without_traceback():
    result = subprocess.run([sys.executable, "-m", "lookout.cli", "reproduce", "nope"], capture_output=True, text=True)
    assert result.returncode == 2
    assert result.stderr.strip().count("\n") == 0 and "Traceback" not in result.stderr


def test_tables_printed_to_a_pipe_keep_their_width(capsys, monkeypatch, tmp_path):
    from lookout.papers._report import Table

    monkeypatch.delenv("COLUMNS", raising=False)
    assert main(["--version"]) == 0  # main sizes the console: the captured output is no terminal
    capsys.readouterr()
    cells = ["a fairly long first column entry", "12345.678 ± 9.87", "0.000123 ± 0.0000456", "diverged in 2 of 2 seeds"]
    summary = {"status": ["finite"], "files": []}
    lookout.cli._print_summary(summary, [Table("wide", ("name", "one", "two", "three"), [cells])], tmp_path)
    text = capsys.readouterr().out
    row = next(line for line in text.splitlines() if cells[0] in line)
    assert all(cell in row for cell in cells) and len(row) > 80, text


@pytest.mark.slow
def test_a_bare_reproduce_writes_under_out_by_name(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main([*REPRODUCE, "--duration", "20"]) == 0
    assert (tmp_path / "out" / "fossen-strand-1999" / "summary.json").is_file()
    assert "written to the folder out/fossen-strand-1999" in capsys.readouterr().out


@pytest.mark.slow
def test_short_reproduce_writes_all_outputs(tmp_path, capsys):
    out = tmp_path / "new" / "folders" / "fs99"  # missing parents are created
    assert main([*REPRODUCE, "--out", str(out), "--duration", "100", "--seed", "3"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    for name in ("fossen_strand_1999.nc", "bode.nc", "summary.json", "fig06_bode.png", "fig09_surge.png", "fig10_sway.png", "fig11_yaw.png"):
        assert (out / name).stat().st_size > 0
    assert summary["config"]["seed"] == 3 and summary["config"]["duration"] == 100.0 and summary["seeds"] == [3]
    assert summary["spr"] == {"surge": "holds", "sway": "holds", "yaw": "holds"}
    assert "RMS estimation error over the second half (seed 3)" in capsys.readouterr().out


@pytest.mark.slow
def test_monte_carlo_run_0_is_the_single_run_to_the_last_bit_and_reports_spread(tmp_path, capsys, monkeypatch):
    """--seed 3 --runs 2 runs seeds 3 and 4; its run 0 is --seed 3 alone, bit for bit; the
    summary gives mean ± std within 80 columns."""
    # the single run through the reproduction's own simulation path (figures and files of a
    # whole reproduction are checked by test_short_reproduce_writes_all_outputs)
    one = fossen_strand_1999.simulate_runs(fossen_strand_1999.Config(duration=20.0, seed=3))
    monkeypatch.setenv("COLUMNS", "80")
    assert main([*REPRODUCE, "--out", str(tmp_path / "two"), "--duration", "20", "--seed", "3", "--runs", "2"]) == 0
    two = xr.load_dataset(tmp_path / "two" / "fossen_strand_1999.nc")
    assert one.seed.values.tolist() == [3] and two.seed.values.tolist() == [3, 4]
    compared = [name for name in one.data_vars if name != "status"]
    assert len(compared) > 20  # truths, estimates, innovations, measurements, inputs
    for name in compared:
        assert np.array_equal(one[name].isel(run=0).values, two[name].isel(run=0).values, equal_nan=True), name
    assert not np.array_equal(two.position_hat.isel(run=0).values, two.position_hat.isel(run=1).values)
    summary = json.loads((tmp_path / "two" / "summary.json").read_text())
    assert summary["runs"] == 2 and summary["status"] == ["finite", "finite"] and summary["seeds"] == [3, 4]
    assert set(summary["rms_second_half_std"]["eta"]) == {"surge", "sway", "yaw"}
    text = capsys.readouterr().out
    table = text[: text.index("units:")]
    assert "2/2 runs finite" in text and "±" in table and "e+" not in table
    assert max(len(line) for line in table.splitlines()) <= 80


@pytest.mark.parametrize(
    "mean, spread, text",
    [
        (1453.0, 100.0, "1450 ± 100"),
        (1507.0, 39.0, "1507 ± 39"),
        (0.662, 0.013, "0.662 ± 0.013"),
        (1.19e-4, 6.6e-6, "(1.190 ± 0.066)e-4"),
        (25745.0, 2051.0, "25700 ± 2100"),
    ],
)
def test_mean_and_spread_share_one_decimal_place(mean, spread, text):
    assert mean_and_spread(mean, spread) == text


@pytest.mark.slow
def test_reproduce_calugi_2002_writes_every_system_and_reports_theorem_2_1(tmp_path, capsys):
    out = tmp_path / "calugi"
    assert main(["reproduce", "calugi-2002-velocity-observer", "--out", str(out), "--duration", "2"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert list(summary["systems"]) == ["pendulum", "two_link", "cart", "furuta"]
    for name, system in summary["systems"].items():
        assert (out / f"calugi_2002_{name}.nc").stat().st_size > 0
        assert system["error_norm"]["final_error"] < 0.05 * system["error_norm"]["initial_error"]  # pendulum: e^-4 after 2 s
        assert set(system["theorem_2_1"]["quantities"]) >= {"effective_gain", "threshold", "radius"}
    pendulum = summary["systems"]["pendulum"]["theorem_2_1"]
    assert pendulum["verdicts"]["theorem_2_1"] == "holds" and pendulum["quantities"]["radius"] is None
    for figure in ("fig2_2_pendulum_velocities.png", "fig2_3_two_link_positions.png", "fig2_8_furuta_velocities.png"):
        assert (out / figure).stat().st_size > 0
    text = capsys.readouterr().out
    assert "Theorem 2.1" in text and "two_link shoulder" in text
    ds = xr.load_dataset(out / "calugi_2002_cart.nc")
    assert ds.joint_position.attrs["units"] == "m" and ds.joint_rate.attrs["units"] == "rad/s"
    assert ds.prismatic_joint.values.tolist() == ["cart"] and ds.revolute_joint.values.tolist() == ["pendulum"]


def test_reproduce_calugi_2002_has_one_run(capsys):
    assert main(["reproduce", "calugi-2002-velocity-observer", "--runs", "2"]) == 2
    assert "--runs must be 1: this reproduction is noise-free" in capsys.readouterr().err


def test_design_sliding_mode_observer_printed_gains_fail_14_and_exit_1(capsys):
    assert main(["design", "sliding-mode-observer"]) == 1
    text = capsys.readouterr().out
    assert "(14) KYP for Sigma_2: P A + A^T P = -Q, B^T P = C, P, Q > 0 [Kim (2002), eq. (14)]: fails" in text
    assert "(not in the verdict) surge: phase of h below 10 w_c > -90 deg: -172.6 > -90 deg: fails" in text
    assert "surge +0.0156 +- 0.1235j" in text and "note: (17) not checked" in text
    assert text.endswith("verdict: FAILS (exit code 1)\n")


def test_design_sliding_mode_observer_kyp_gains_pass_and_json_is_strict(capsys):
    assert main(["design", "sliding-mode-observer", "--gains", "kyp", "--disturbance", "1e5,1e5,1e6", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["holds"] is True and result["verdicts"]["kyp_14"] == "holds"
    assert result["verdicts"]["switching_gain_17"] == "holds" and result["inputs"]["disturbance"] == [1e5, 1e5, 1e6]
    assert result["switching_gain_17"]["quantities"]["required_gain"][0] == pytest.approx(2.05, rel=1e-2)
    (surge,) = [item for item in result["switching_gain_17"]["inequalities"] if item["name"] == "surge"]
    assert surge["right"] == pytest.approx(2.05, rel=1e-2) and surge["left"] == 10.0 and surge["units"] == "m/s"


#: One run of each design command, and its exit code.
DESIGNS = {
    "passive-observer": (["--wave-period", "7"], 0),
    "sliding-mode-observer": (["--gains", "kyp"], 0),
    "adaptive-observer": ([], 1),
    "adaptive-arm": (["--arm", "pendulum"], 0),
    "tracking-gains": (["--start", "measured"], 1),
}


@pytest.mark.parametrize("design", list(DESIGNS))
@pytest.mark.slow
def test_every_design_command_prints_and_dumps_one_layout(design, capsys):
    """The same JSON keys (the design, its inputs, then the report's one layout), a block
    per condition with its inequalities, exit code 0 exactly when the report holds; the
    text gives one line per inequality with its numbers, verdict and margin, and ends
    with the verdict line."""
    argv, code = DESIGNS[design]
    assert main(["design", design, *argv, "--json"]) == code
    result = json.loads(capsys.readouterr().out)
    assert list(result) == ["design", "inputs", "title", "verdict", "holds", "verdicts", *result["verdicts"], "quantities", "summary", "notes"]
    assert result["design"] == design and result["holds"] is (result["verdict"] == "holds") is (code == 0)
    flat = []
    for key, verdict in result["verdicts"].items():
        block = result[key]
        assert block["key"] == key and block["verdict"] == verdict and block["source"] and block["reason"]
        flat += block["inequalities"]
    assert flat
    assert {item["verdict"] for item in flat} <= {"holds", "fails", "unverified"}
    assert main(["design", design, *argv]) == code
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"{result['title']}: {result['verdict']}"
    assert lines[-1] == f"verdict: {'passes' if code == 0 else 'FAILS'} (exit code {code})"
    for item in flat:
        assert any(line.startswith(f"    {item['name']}: {item['relation']}: ") and f": {item['verdict']}, margin " in line for line in lines)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--gains", "mine"], "--gains must be one of printed, kyp; got 'mine'"),
        (["--switching-gain", "-1"], "--switching-gain must be one finite number >= 0"),
        (["--boundary-layer", "0,1,1"], "--boundary-layer must be one finite positive number"),
        (["--velocity-gain", "1e20"], "--velocity-gain must lie within 1e-12..1e12"),
        (["--disturbance", "nan"], "--disturbance must be one finite number >= 0"),
    ],
)
def test_design_sliding_mode_observer_bad_input_exits_2_with_one_line(argv, message, capsys):
    assert main(["design", "sliding-mode-observer", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_components_lists_the_design_rules_of_each_kind(capsys):
    """The kinds with gain-synthesis rules, the default first; one entry per rule of a kind."""
    assert main(["components", "--json"]) == 0
    rules = {(entry["role"], entry["kind"]): entry["designs"] for entry in json.loads(capsys.readouterr().out) if entry["designs"]}
    assert rules == {
        ("observer", "passive"): ["fossen-strand-1999", "gains"],
        ("observer", "sliding-mode"): ["kim-2002", "gains"],
        ("observer", "earth-fixed"): ["gains", "wondergem-2009"],
        ("controller", "tracking"): ["gains", "wondergem-2009"],
        ("controller", "pid"): ["pole-placement", "gains"],
    }
    assert main(["components", "tracking", "--json"]) == 0
    entries = json.loads(capsys.readouterr().out)
    assert [entry["design"] for entry in entries] == ["gains", "wondergem-2009"]
    keys = [{p["name"] for p in entry["parameters"]} for entry in entries]
    assert keys[0] == {"ship", "natural_frequency", "damping_ratio"} and {"reference_speed_max", "start_position", "margin"} <= keys[1]


# ----------------------------------------------------------------------------------
# the command's start: --version and --help without JAX, and the compilation cache

HEAVY_MODULES = ("jax", "jaxlib", "numpy", "xarray", "equinox", "scipy", "matplotlib")


@pytest.mark.parametrize(
    "argv",
    [["--version"], ["--help"], [], ["run", "--help"], ["replay", "--help"], ["design", "passive-observer", "--help"], ["campaign", "run", "--help"]],
)
def test_version_and_help_answer_without_importing_jax_or_numpy(argv):
    """The command's start (lookout.cli, what it registers, lookout's __init__) imports
    nothing that computes; each command imports that when it runs."""
    script = (
        "import sys, io, contextlib; from lookout.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()) as out: code = main(sys.argv[1:])\n"
        f"print(code, out.getvalue().startswith(('lookout ', 'Usage: lookout')), sorted(set({HEAVY_MODULES!r}) & set(sys.modules)))"
    )
    result = subprocess.run([sys.executable, "-c", script, *argv], capture_output=True, text=True)
    assert result.stdout.strip() == f"{2 if argv == [] else 0} True []", result.stdout + result.stderr


def _scenario_of_seconds(folder, seconds: float):
    """examples/dp-observer.toml with a shorter duration."""
    text = open(os.path.join(os.path.dirname(__file__), "..", "examples", "dp-observer.toml")).read()
    assert "duration = 1500.0\n" in text
    path = folder / "short.toml"
    path.write_text(text.replace("duration = 1500.0\n", f"duration = {seconds}\n"))
    return path


def _command_environment(cache_home, **variables):
    """This process's environment without its JAX cache settings (the tests' conftest sets
    its own), the user's cache folder in ``cache_home``, and ``variables``."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JAX_COMPILATION_CACHE", "JAX_PERSISTENT_CACHE", "LOOKOUT_"))}
    return env | {"XDG_CACHE_HOME": str(cache_home)} | variables


@pytest.mark.slow
def test_a_second_run_of_a_file_loads_the_programs_the_first_compiled_and_the_switch_turns_it_off(tmp_path):
    scenario = _scenario_of_seconds(tmp_path, 20.0)
    cache = tmp_path / "cache" / "lookout" / "jax"
    # every program is cached whatever its compile time here (the command's own
    # threshold is a setting, not what this checks); the second run logs its cache hits
    env = _command_environment(tmp_path / "cache", JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0")
    first = subprocess.run(
        [sys.executable, "-m", "lookout.cli", "run", str(scenario), "--out", str(tmp_path / "one")], capture_output=True, text=True, env=env
    )
    assert first.returncode == 0, first.stderr
    entries = sorted(path.name for path in cache.iterdir())
    assert entries and all(name.endswith("-cache") for name in entries), entries
    second = subprocess.run(
        [sys.executable, "-m", "lookout.cli", "run", str(scenario), "--out", str(tmp_path / "two")],
        capture_output=True,
        text=True,
        env=env | {"JAX_LOG_COMPILES": "1"},
    )
    assert second.returncode == 0, second.stderr
    hits = second.stderr.count("Persistent compilation cache hit")
    assert hits >= 1 and "PERSISTENT COMPILATION CACHE MISS" not in second.stderr, second.stderr[-2000:]
    assert xr.open_dataset(tmp_path / "one" / "run.nc").equals(xr.open_dataset(tmp_path / "two" / "run.nc"))

    off = tmp_path / "off"
    env = _command_environment(off, JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0", LOOKOUT_COMPILATION_CACHE="0")
    result = subprocess.run(
        [sys.executable, "-m", "lookout.cli", "run", str(scenario), "--out", str(tmp_path / "three")], capture_output=True, text=True, env=env
    )
    assert result.returncode == 0, result.stderr
    assert not (off / "lookout").exists()  # (matplotlib keeps its own cache there too)


@pytest.mark.parametrize("value", ["maybe", "2", "off please"])
def test_a_compilation_cache_switch_that_is_neither_on_nor_off_is_refused_in_one_line(value, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("LOOKOUT_COMPILATION_CACHE", value)
    assert main(["run", str(tmp_path / "x.toml"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: LOOKOUT_COMPILATION_CACHE must be 0") and repr(value) in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_version_and_help_answer_whatever_the_compilation_cache_switch_says(capsys, monkeypatch):
    monkeypatch.setenv("LOOKOUT_COMPILATION_CACHE", "maybe")
    assert main(["--version"]) == 0 and main(["--help"]) == 0
    assert "LOOKOUT_COMPILATION_CACHE" not in capsys.readouterr().err


def test_a_cache_folder_that_cannot_be_read_and_written_is_named_in_one_line_and_left_out(tmp_path, monkeypatch, capsys):
    import sys

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.delenv("LOOKOUT_COMPILATION_CACHE", raising=False)
    monkeypatch.delenv("JAX_COMPILATION_CACHE_DIR", raising=False)
    monkeypatch.delitem(sys.modules, "jax")  # as before a command imports JAX
    monkeypatch.setattr(lookout._commandline.os, "access", lambda path, mode: False)
    assert lookout._commandline.use_compilation_cache() is None
    err = capsys.readouterr().err
    assert err.startswith(f"note: the compilation cache folder {tmp_path / 'lookout' / 'jax'} cannot be read and written") and err.count("\n") == 1
    assert "JAX_COMPILATION_CACHE_DIR" not in os.environ


def test_the_compilation_cache_folder_follows_the_xdg_rule_and_the_switch(tmp_path, monkeypatch):
    folder = lookout._commandline.compilation_cache_folder
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    for on in ("1", "on", "yes", "true", ""):
        monkeypatch.setenv("LOOKOUT_COMPILATION_CACHE", on)
        assert folder() == tmp_path / "xdg" / "lookout" / "jax"
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/cache")  # not absolute: ignored, as the XDG rule says
    assert folder() == tmp_path / "home" / ".cache" / "lookout" / "jax"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert folder() == tmp_path / "home" / ".cache" / "lookout" / "jax"
    for off in ("0", "off", "OFF", "no", "false"):
        monkeypatch.setenv("LOOKOUT_COMPILATION_CACHE", off)
        assert folder() is None


def test_a_cache_folder_jax_was_given_wins_over_the_commands(tmp_path, monkeypatch):
    """The tests' conftest (like a user) gives JAX its own folder: the command leaves it."""
    import jax

    given = jax.config.jax_compilation_cache_dir
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.delenv("LOOKOUT_COMPILATION_CACHE", raising=False)
    assert given is not None and lookout._commandline.use_compilation_cache() is None
    assert jax.config.jax_compilation_cache_dir == given and not any(tmp_path.iterdir())


@pytest.mark.parametrize("seed", range(5))
def test_trimming_the_cache_removes_the_least_recently_used_files_until_the_bound_holds(seed, tmp_path):
    rng = np.random.default_rng(seed)
    count = int(rng.integers(1, 12))
    sizes = [int(s) for s in rng.integers(0, 5000, count)]
    used = rng.permutation(count) * 1000.0 + 1e9  # distinct times of last use
    for i, (size, time) in enumerate(zip(sizes, used)):
        (tmp_path / f"entry{i}-cache").write_bytes(b"x" * size)
        os.utime(tmp_path / f"entry{i}-cache", (time, time - 500.0 * (i % 2)))  # (access, modification)
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "kept").write_bytes(b"x" * 10_000)  # a subfolder is not the cache's
    bound = int(rng.integers(0, sum(sizes) + 2))
    lookout._commandline.trim_folder(tmp_path, bound)
    # expected: the fewest least recently used files whose removal leaves at most the bound
    by_use = sorted(range(count), key=lambda i: used[i])
    removed = next(k for k in range(count + 1) if sum(sizes[i] for i in by_use[k:]) <= bound)
    expected = {f"entry{i}-cache" for i in by_use[removed:]}
    assert {path.name for path in tmp_path.iterdir() if path.is_file()} == expected
    assert (tmp_path / "sub" / "kept").exists()
    lookout._commandline.trim_folder(tmp_path / "missing", 0)  # no folder yet: nothing to do


def test_a_long_simulation_says_its_time_left_after_the_segment_that_compiles():
    from lookout._commandline import LONG_RUN_SECONDS, time_left

    # 100 s compiling the first 5 % of the records, then 5 % more in 10 s: 18 segments of 10 s left
    line = time_left([(100.0, 50.0), (110.0, 100.0)], 1000.0, 0.0)
    assert (
        line == "simulating: about 3 min 00 s left (10% of the records in 1 min 50 s, compilation included; the pace is that of the last 50 records)"
    )
    assert time_left([(100.0, 50.0), (100.0 + LONG_RUN_SECONDS / 20, 100.0)], 1000.0, 0.0) is None  # 18 x 1.5 s: under the bound
    assert time_left([(100.0, 500.0), (110.0, 1000.0)], 1000.0, 0.0) is None  # done
