import json
import subprocess
import sys

import pytest

from lookout.cli import main


def test_list(capsys):
    assert main(["list"]) == 0
    assert "fossen-strand-1999" in capsys.readouterr().out


def test_design_json_reports_gains_verdicts_and_frequency_response(capsys, tmp_path):
    bode = tmp_path / "bode.png"
    code = main(["design", "passive-observer", "--wave-period", "7.0", "--frequency", "0.8976", "--frequency", "0.1", "--bode", str(bode), "--json"])
    assert code == 0
    result = json.loads(capsys.readouterr().out)
    assert {"K1", "K2", "tuning_rule", "spr", "frequency_response"} <= set(result)
    assert round(result["K1"][0][0], 4) == -2.2059 and round(result["K1"][3][0], 4) == 1.6157
    assert result["tuning_rule"]["holds"] and result["spr"]["holds"]
    first = result["frequency_response"][0]
    assert set(first) == {"frequency", "magnitude", "phase_deg"}
    assert bode.stat().st_size > 0


def test_design_text_output(capsys):
    assert main(["design", "passive-observer", "--wave-frequency", "0.8976", "--frequency", "0.5"]) == 0
    out = capsys.readouterr().out
    assert "tuning rule (48): holds" in out and "KYP certificate verified" in out and "|h0(j0.5)|" in out


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["design", "passive-observer", "--wave-frequency", "abc"], "--wave-frequency"),
        (["design", "passive-observer", "--wave-frequency", "1.2"], "cutoff_frequency must exceed wave_frequency"),
        (["design", "passive-observer", "--wave-frequency", "0.9", "--bias-time-constant", "-3"], "bias_time_constant must be positive"),
        (["design", "passive-observer"], "give exactly one of --wave-frequency and --wave-period"),
        (["reproduce", "nope"], "unknown reproduction 'nope'"),
        (["reproduce", "fossen-strand-1999", "--duration", "-5"], "duration: Input should be greater than 0"),
        (["reproduce", "fossen-strand-1999", "--duration", "10.05"], "duration (10.05 s) must be an integer multiple"),
        (["design", "passive-observer", "--wave-frequency", "0.9", "--bogus"], "No such option: --bogus"),
    ],
)
def test_bad_input_is_one_line_with_exit_code_2(argv, fragment, capsys):
    assert main(argv) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and fragment in lines[0]
    assert "Traceback" not in captured.err + captured.out


def test_entry_point_exit_code_without_traceback():
    result = subprocess.run([sys.executable, "-m", "lookout.cli", "reproduce", "nope"], capture_output=True, text=True)
    assert result.returncode == 2
    assert result.stderr.strip().count("\n") == 0 and "Traceback" not in result.stderr


def test_short_reproduce_writes_all_outputs(tmp_path, capsys):
    out = tmp_path / "fs99"
    assert main(["reproduce", "fossen-strand-1999", "--out", str(out), "--duration", "100", "--seed", "3"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    for name in ("fossen_strand_1999.nc", "summary.json", "fig06_bode.png", "fig09_surge.png", "fig10_sway.png", "fig11_yaw.png"):
        assert (out / name).stat().st_size > 0
    assert summary["config"]["seed"] == 3 and summary["config"]["duration"] == 100.0
    assert "RMS over the second half" in capsys.readouterr().out


def test_reproduce_with_several_runs_reports_spread(tmp_path, capsys):
    out = tmp_path / "mc"
    assert main(["reproduce", "fossen-strand-1999", "--out", str(out), "--duration", "60", "--runs", "2"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["runs"] == 2 and summary["status"] == ["finite", "finite"]
    assert set(summary["rms_second_half_std"]["eta"]) == {"surge", "sway", "yaw"}
    assert "2/2 runs finite" in capsys.readouterr().out


def test_design_normalized_gains_convert_like_the_default(capsys):
    assert main(["design", "passive-observer", "--wave-frequency", "0.8976", "--json"]) == 0
    default = json.loads(capsys.readouterr().out)
    argv = ["design", "passive-observer", "--wave-frequency", "0.8976", "--normalized", "--velocity-gain", "0.1,0.1,0.01", "--bias-gain", "0.01,0.01,0.001", "--json"]
    assert main(argv) == 0
    normalized = json.loads(capsys.readouterr().out)
    assert normalized["velocity_injection_gain"] == pytest.approx(default["velocity_injection_gain"], rel=1e-12)
    assert normalized["bias_injection_gain"] == pytest.approx(default["bias_injection_gain"], rel=1e-12)
    assert main(["design", "passive-observer", "--wave-frequency", "0.8976", "--velocity-gain", "5e4", "--bias-gain", "2e3", "--json"]) == 0
    si = json.loads(capsys.readouterr().out)
    assert si["velocity_injection_gain"] == [5e4, 5e4, 5e4] and si["bias_injection_gain"] == [2e3, 2e3, 2e3]
