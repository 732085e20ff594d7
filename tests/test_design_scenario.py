"""lookout design FILE: the conditions of a scenario file's components, as the paper
commands check them, and gains proposed inside them."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import pytest

from lookout.cli import main
from lookout.scenario.composition import set_path

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def _design(capsys, *args) -> tuple[int, dict | str]:
    capsys.readouterr()
    code = main(["design", *map(str, args)])
    out = capsys.readouterr()
    return code, (json.loads(out.out) if "--json" in args and out.out.strip() else out.out + out.err)


def test_the_scenario_of_the_papers_observer_gives_the_passive_observer_commands_verdicts(capsys):
    """examples/dp-observer.toml is Fossen & Strand's observer with their (60) at w_o =
    0.8976 rad/s: the same inequalities, with the same numbers, as the paper's command."""
    code, scenario = _design(capsys, EXAMPLES / "dp-observer.toml", "--json")
    paper_code, paper = _design(capsys, "passive-observer", "--wave-frequency", "0.8976", "--json")
    assert code == paper_code == 0
    assert scenario["verdicts"] == paper["verdicts"] and scenario["design"] == "scenario"
    assert scenario["inputs"]["components"] == [{"role": "observer", "kind": "passive"}]
    for key in paper["verdicts"]:
        ours = [side for i in scenario[key]["inequalities"] for side in (i["left"], i["right"])]
        theirs = [side for i in paper[key]["inequalities"] for side in (i["left"], i["right"])]
        assert ours == pytest.approx(theirs, rel=1e-9), key


def test_kims_printed_gains_fail_14_and_the_proposed_gains_pass_when_written_into_the_file(capsys, tmp_path):
    code, report = _design(capsys, EXAMPLES / "kim-closed-loop.toml", "--json")
    assert code == 1 and report["verdicts"]["kyp_14"] != "holds"
    code, proposed_json = _design(capsys, EXAMPLES / "kim-closed-loop.toml", "--propose", "--json")
    # the verdict and exit code are the file's; the proposal's are apart
    assert code == 1 and not proposed_json["holds"] and proposed_json["verdicts"] == report["verdicts"]
    proposal = proposed_json["proposal"]
    assert proposal["holds"]
    document = tomllib.loads((EXAMPLES / "kim-closed-loop.toml").read_text())
    for component in proposed_json["inputs"]["components"]:
        for key, value in component["proposed"].items():
            set_path(document, key, value)
    proposed = tmp_path / "proposed.toml"
    proposed.write_text(_toml(document))
    code, again = _design(capsys, proposed, "--json")
    assert code == 0 and again["verdicts"] == proposal["verdicts"]


def test_propose_on_a_failing_file_prints_the_files_verdict_first_and_exits_1(capsys):
    code, text = _design(capsys, EXAMPLES / "kim-closed-loop.toml", "--propose")
    file_verdict = text.index("verdict of ")
    proposal_verdict = text.index("verdict with the proposed gains: passes")
    assert code == 1 and "FAILS (exit code 1)" in text[file_verdict:proposal_verdict] and file_verdict < proposal_verdict


def _toml(document: dict) -> str:
    from lookout.scenario._toml import dumps

    return dumps(document, {}, "")


def test_a_file_without_conditions_a_missing_file_and_a_bad_file_are_answered_in_one_line(capsys, tmp_path):
    code, text = _design(capsys, EXAMPLES / "luenberger-dp.toml")
    assert code == 1 and "observer luenberger" in text and "declares conditions" in text
    code, text = _design(capsys, tmp_path / "none.toml")
    assert code == 2 and text.strip() == f"error: {tmp_path / 'none.toml'}: no such file"
    bad = tmp_path / "bad.toml"
    bad.write_text('preset = "fossen-strand-1999"\n[observer]\nbias_time_constant = -1.0\n')
    code, text = _design(capsys, bad)
    assert code == 2 and len(text.strip().splitlines()) == 1 and "observer.bias_time_constant (line 3)" in text
