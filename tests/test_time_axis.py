"""One time axis (issue 28, item 5) and an exit status that says it all (item 7).

`t` counts from the start of the recording as `dkreason info` and `ros2 bag info` show it (its
first record, of any topic), whatever formulas are monitored; `--start`/`--end` take +SECONDS,
seconds on the recording's clock or ISO 8601 times and bound what is judged.  The recordings
are made here: an epoch clock whose start, 1780000000.123456789 s, no float holds exactly.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from dkreason.cli import main
from dkreason.stream.recording import Row, write_recording
from dkreason.stream.units import since

from .conftest import REPO

S = 10**9
START = 1_780_000_000 * S + 123_456_789  # ns: 2026-05-28T20:26:40.123456789Z
POSE = "float32 x\nfloat32 y\nfloat32 theta\nfloat32 linear_velocity\nfloat32 angular_velocity\n"
TYPE = "turtlesim/msg/Pose"


def pose(x: float = 0.0, theta: float = 0.0) -> dict[str, Any]:
    return {"x": x, "y": 0.0, "theta": theta, "linear_velocity": 0.0, "angular_velocity": 0.0}


def recording(path: Path) -> Path:
    """/robot1/cmd (read by no spec) opens the recording; Theta comes at 10 Hz from 1 s on,
    X at 1 Hz from 2 s on, X = i at 2 + i s, for 30 s."""
    rows: list[Row] = [("/robot1/cmd", TYPE, START, pose())]
    rows += [("/robot1/b", TYPE, START + S + k * S // 10, pose(theta=0.5)) for k in range(300)]
    rows += [("/robot1/pose", TYPE, START + (2 + i) * S, pose(x=i)) for i in range(30)]
    write_recording(path, "bare-mcap", {TYPE: POSE}, rows)
    return path


def config(tmp_path: Path) -> Path:
    (tmp_path / "r.sslt").write_text(
        "topic pose:turtlesim/Pose contains X(me) = msg.x\n"
        "topic b:turtlesim/Pose contains Theta(me) = msg.theta\n"
    )
    path = tmp_path / "r.toml"
    path.write_text(
        f'[platforms.robot1]\nontology = "{REPO}/tests/data/turtles/turtle.ttl"\n'
        'specs = "r.sslt"\nnamespace = "/robot1"\n'
    )
    return path


@pytest.fixture
def run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> Any:
    """`dkreason monitor` over the recording: (exit status, stdout, stderr)."""
    args = ["--config", str(config(tmp_path)), "--source", str(recording(tmp_path / "r.mcap"))]

    def monitor(*argv: str) -> tuple[int, str, str]:
        code = main(["monitor", *args, *argv])
        out = capsys.readouterr()
        return code, out.out, out.err

    return monitor


def lines(out: str) -> list[dict[str, Any]]:
    return [json.loads(line) for line in out.splitlines()]


X_HIGH = "always (X[me] < 20)"  # violated at 22 s, where X reaches 20
THETA = "always (Theta[me] < 100)"


def test_t_counts_from_the_recordings_start_whatever_else_is_monitored(run: Any) -> None:
    """Alone, X's first sample (2 s) was t+0; beside Theta, Theta's (1 s): the same event
    printed two times, neither from the recording's start, and with a float's error."""
    for formulas in ([X_HIGH], [X_HIGH, THETA], [THETA, X_HIGH]):
        code, out, _ = run("--json", *formulas)
        (violated,) = [e for e in lines(out) if e["formula"] == X_HIGH]
        assert code == 1 and violated["verdict"] is False
        assert violated["t"] == 22 and violated["time"] == 1780000022.1234567
        code, out, _ = run(*formulas)
        assert "at t+22 s (2026-05-28T20:27:02.123Z): VIOLATED  always (X[me] < 20)" in out


def test_the_summary_table_shows_t(run: Any) -> None:
    _, out, _ = run(X_HIGH)
    (row,) = [line for line in out.splitlines() if line.startswith("│ always")]
    assert "│ 22 " in row and "1780000022" not in row


def test_t_is_exact_to_the_nanosecond_never_a_floats_error(run: Any) -> None:
    """X's first sample, 2 s in, violates: t is 2 (it was -8.9e-08, counted from that sample
    through the float of an epoch time)."""
    code, out, _ = run("--json", "always (X[me] > 0)")
    (verdict,) = lines(out)
    assert code == 1 and verdict["t"] == 2


def test_t_reads_as_people_read_it() -> None:
    """Whole seconds without a fraction; a header stamped before the recording's first record
    is before its start, `t-…` (it read `t+-1.13e-07 s`)."""
    assert [since(t) for t in (22, 1.0, 0.279999952, -0.02)] == [
        "t+22 s",
        "t+1 s",
        "t+0.279999952 s",
        "t-0.02 s",
    ]


def test_end_bounds_what_is_judged_without_a_violation_per_later_message(run: Any) -> None:
    """`--end +10`: the messages after it are skipped (no "outside the requested span" line
    for each), and the end of the window is the end of the data: X's last value, 9.9 s old
    by the recording's end, is not judged stale past it."""
    code, out, _ = run("--json", "--end", "+10", "always (X[me] < 100)")
    assert code == 0
    (verdict,) = lines(out)
    assert verdict["verdict"] is True and verdict["t"] == 10 and verdict["at_end"]
    code, out, _ = run("--end", "+10", "always (X[me] < 100)")
    assert code == 0 and "violation at" not in out and "outside" not in out


def test_start_takes_seconds_from_the_start_and_iso_8601_times(
    run: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    """X > 5 fails 2 s in; from 8 s on (the sample with X = 6) it holds."""
    assert run("always (X[me] > 5)")[0] == 1
    for start in ("+8", "2026-05-28T20:26:48.123456789Z", "1780000008.123456789"):
        code, out, _ = run("--json", "--start", start, "always (X[me] > 5)")
        (verdict,) = lines(out)
        assert code == 0 and verdict["verdict"] is True, start
    with pytest.raises(SystemExit) as bad:
        run("--start", "2026-05-28T20:26:48", "always (X[me] > 5)")
    assert bad.value.code == 2 and "has no time zone" in capsys.readouterr().err


def test_an_end_before_the_recording_is_bad_input_naming_the_relative_form(run: Any) -> None:
    """`--end 10` on an epoch clock is 1970: nothing would be judged."""
    code, out, err = run("--end", "10", "always (X[me] < 100)")
    assert code == 2
    assert "before the recording starts" in err and "+10" in err


def test_the_exit_status_says_whether_stream_constraints_held_when_asked(run: Any) -> None:
    """Theta comes every 0.1 s where --period 0.5 expects 0.5 s: constraint violations,
    counted per kind in the summary, exit 1 only with --fail-on-constraint."""
    argv = ["--period", "0.5", "--deviation", "0.01", THETA]
    code, out, _ = run(*argv)
    assert code == 0
    assert "stream constraint violations: 299 sample_period" in out
    assert run("--fail-on-constraint", *argv)[0] == 1
    assert run("--fail-on-constraint", "always (X[me] < 100)")[0] == 0
    code, out, _ = run("always (X[me] < 100)")
    assert code == 0 and "stream constraint violations: none" in out
