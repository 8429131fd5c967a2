"""`dkreason progress`: the thesis formulas over a state file, JSON lines, exit status."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from dkreason.cli import main

from .conftest import SCENARIOS, formulas

STATES = Path(__file__).parent / "data" / "thesis-states.jsonl"

# Hand check of tests/data/thesis-states.jsonl (times 0, 1.5, 3, 4, 5):
# F1 needs Altitude[uav1] > Altitude[uav2]: 90 > 100 fails at time 3.
# F2 needs every UAV speed above every car speed: Speed[uav2] = 56 < Speed[car3] = 57 at 5.
# F3 needs Close[uav1, x] for x in {uav1, uav2}: Close[uav1, uav2] is false at 4.
HAND_CHECK = {"F1": (False, 3), "F2": (False, 5), "F3": (False, 4)}


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, list[dict[str, Any]]]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, [json.loads(line) for line in out.out.splitlines()]


@pytest.mark.parametrize("spelling", ["", "-ascii"])
def test_thesis_formulas_give_the_hand_checked_verdicts(
    capsys: pytest.CaptureFixture[str], spelling: str
) -> None:
    assert SCENARIOS is not None
    table = formulas()
    argv = [table[f"{name}{spelling}"] for name in HAND_CHECK]
    code, lines = run(
        capsys,
        "progress",
        "--states",
        str(STATES),
        "--config",
        str(SCENARIOS / "single.toml"),
        "--json",
        *argv,
    )
    assert code == 1
    got = {line["formula"]: (line["verdict"], line["time"]) for line in lines}
    assert got == {argv[n]: HAND_CHECK[name] for n, name in enumerate(HAND_CHECK)}
    assert all(line["at_end"] is False for line in lines)


def test_one_line_per_formula_argument_and_exit_status(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    states = tmp_path / "s.jsonl"
    states.write_text(
        '{"time": 0, "values": {"P": true, "X": 1}}\n'
        '{"time": 2.5, "values": {"P": false, "X": null}}\n'
    )
    code, lines = run(
        capsys,
        "progress",
        "--states",
        str(states),
        "--json",
        "eventually P",
        "eventually P",
        "always (X > 0)",
    )
    assert code == 3  # nothing violated, one unknown
    assert [line["formula"] for line in lines] == ["eventually P", "eventually P", "always (X > 0)"]
    assert lines[0] == {
        "formula": "eventually P",
        "verdict": True,
        "time": 0,
        "at_end": False,
        "witness": None,
    }
    assert lines[2]["verdict"] is None and lines[2]["at_end"] is True
    assert lines[2]["time"] == 2.5
    assert lines[2]["unknown"] == [{"feature": "X", "from": 2.5, "to": 2.5}]


@pytest.mark.parametrize(
    ("content", "says"),
    [
        ('{"time": 0, "values": {"P": true}}\n{"time": 1, "values": \n', "s.jsonl:2:"),
        ('{"time": 0}\n', 's.jsonl:1: expected {"time": …, "values": {…}}'),
        ('{"time": 0, "values": {"Q": true}}\n', "the state at time 0 has no value for P"),
    ],
)
def test_bad_state_files_are_one_line_errors(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, content: str, says: str
) -> None:
    states = tmp_path / "s.jsonl"
    states.write_text(content)
    code = main(["progress", "--states", str(states), "always P"])
    out = capsys.readouterr()
    assert code == 2 and out.err.count("\n") == 1 and says in out.err


def test_quantifiers_need_a_knowledge_base(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    states = tmp_path / "s.jsonl"
    states.write_text('{"time": 0, "values": {}}\n')
    code = main(["progress", "--states", str(states), "forall x in UAV: Speed[x] > 1"])
    assert code == 2 and "needs a knowledge base" in capsys.readouterr().err


def test_states_may_hold_strings_and_types_are_checked_against_their_use(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    states = tmp_path / "s.jsonl"
    states.write_text(
        "".join(
            json.dumps({"time": t, "values": {"Mode[a]": m, "Alt[a]": 5}}) + "\n"
            for t, m in enumerate(["AUTO", "AUTO", "MANUAL"])
        )
    )
    code, lines = run(
        capsys,
        "progress",
        "--states",
        str(states),
        "--json",
        'always (Mode[a] == "AUTO")',
        "always (abs(Alt[a] - 6) < 2)",
    )
    assert code == 1 and [(v["verdict"], v["time"]) for v in lines] == [(False, 2), (True, 2)]
    code = main(["progress", "--states", str(states), "always (Mode[a] > 3)"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "s.jsonl:1: Mode[a] is a string ('AUTO'), but a formula uses it as a number" in err


def test_a_window_the_state_file_ends_in_is_pending_unless_the_end_is_finite(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    states = tmp_path / "s.jsonl"
    states.write_text('{"time": 0, "values": {"P": false}}\n{"time": 3, "values": {"P": false}}\n')
    formula = "eventually[0, 5] P"
    code, (open_,) = run(capsys, "progress", "--states", str(states), "--json", formula)
    assert code == 3 and open_["verdict"] is None
    assert open_["pending"] == (
        "eventually[0, 5] P: window [0, 5] cut off at the end of the data, 3 s of 5 s seen"
    )
    argv = ["progress", "--states", str(states), "--json", "--end-of-data", "finite", formula]
    code, (finite,) = run(capsys, *argv)
    assert code == 1 and (finite["verdict"], finite["at_end"]) == (False, True)
