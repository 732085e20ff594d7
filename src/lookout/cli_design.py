"""``lookout design FILE``: the conditions of every component of a scenario file that has
any (:mod:`lookout.design`), with the verdicts and JSON of the other ``design`` commands."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from lookout._commandline import console
from lookout._json import json_safe
from lookout._validation import InputError

#: How a design command prints a report's verdict.
DESIGN_VERDICTS = {"holds": "passes", "fails": "FAILS", "unverified": "NOT ESTABLISHED"}


def design_scenario(
    scenario: Annotated[Path, typer.Argument(metavar="FILE", help="A scenario file (lookout run FILE runs it).")],
    propose: Annotated[
        bool, typer.Option("--propose", help="Propose gains inside the conditions (the file's own when they hold), as file keys, and check them.")
    ] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object instead of the report.")] = False,
) -> None:
    """The conditions of each component of a scenario file that has any, for the file's
    own plant, gains and sea: the observer's and the controller's (lookout components
    KIND says which kinds have them).

    With --propose, the proposed gains and their conditions follow the file's, apart
    (JSON: under "proposal"). Exit code, always the file's own gains': 0 when every
    condition holds, 1 when one fails (the report or JSON is still printed), 2 for bad
    input (with ``--json``, an object whose ``error`` is the message, on stdout; the
    message on stderr too).
    """
    from lookout.design import combined, combined_proposal, component_designs
    from lookout.scenario._toml import FileError
    from lookout.scenario.file import load

    def refuse(message: str):
        """Bad input: with --json, one JSON object on stdout as well (exit code 2 either way)."""
        if as_json:
            print(json.dumps({"design": "scenario", "inputs": {"scenario": str(scenario), "propose": propose}, "error": message}))
        return InputError(message)

    try:
        spec = load(scenario, runs=1)
    except FileError as error:
        raise refuse(str(error)) from None
    composition = spec.composition
    try:
        designs = component_designs(composition, propose=propose)
    except ValueError as error:
        raise refuse(f"{scenario}: {error}") from None
    report = combined(designs, str(scenario))
    proposal = combined_proposal(designs, str(scenario))
    code = 0 if report.holds else 1
    inputs = {
        "scenario": str(scenario),
        "propose": propose,
        "components": [{"role": d.role, "kind": d.kind, **({"proposed": d.proposed} if d.proposed is not None else {})} for d in designs],
    }
    if as_json:
        document = {"design": "scenario", "inputs": inputs, **report.to_dict()}
        if proposal is not None:
            document["proposal"] = proposal.to_dict()
        print(json.dumps(json_safe(document), allow_nan=False))
    else:
        for line in report.lines():
            console.print(line, highlight=False, markup=False)
        if not designs:
            console.print(
                f"{scenario}: none of its components ({', '.join(f'{r} {k}' for r, k in composition.kinds.items())}) declares conditions",
                highlight=False,
                markup=False,
            )
        console.print(f"verdict of {scenario}: {DESIGN_VERDICTS[report.verdict]} (exit code {code})", highlight=False, markup=False)
        if proposal is not None:
            console.print("", highlight=False)
            for line in proposal.lines():
                console.print(line, highlight=False, markup=False)
            console.print(
                f"verdict with the proposed gains: {DESIGN_VERDICTS[proposal.verdict]} (write them into {scenario} to use them; "
                f"the exit code is the file's)",
                highlight=False,
                markup=False,
            )
    if code:
        raise typer.Exit(code=code)


def register(design_app: typer.Typer) -> None:
    """Add ``scenario`` to the ``design`` commands (``lookout design FILE`` runs it)."""
    design_app.command("scenario")(design_scenario)


def route(argv: list[str], commands: set[str]) -> list[str]:
    """``design FILE ...`` as ``design scenario FILE ...``: a first argument that is not one
    of the ``design`` commands (nor an option) is a scenario file."""
    if len(argv) >= 2 and argv[0] == "design" and argv[1] not in commands and not argv[1].startswith("-"):
        return ["design", "scenario", *argv[1:]]
    return argv
