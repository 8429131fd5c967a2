"""`dkreason init`: a starter model from a recording that `match` and `monitor` take as it is."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dkreason import KnowledgeManager
from dkreason.cli import main
from dkreason.stream.recording import write_recording

from .test_monitor import SPEEDING, car_rows
from .test_monitor import TYPES as CAR_TYPES

BATTERY = "x/msg/Battery"
ODOM = "x/msg/Odom"
TYPES = {
    BATTERY: "std_msgs/Header header\nfloat32 percentage\nbool charging\nstring status\n",
    ODOM: "geometry_msgs/Point position\nfloat64[] covariance\n",
}
S = 10**9


def rows() -> list[tuple[str, str, int, dict[str, object]]]:
    """The battery drains from 1.0 by 0.1 a second; the robot drives along x."""
    out: list[tuple[str, str, int, dict[str, object]]] = []
    for n in range(6):
        out.append(
            (
                "/rover/battery",
                BATTERY,
                n * S,
                {"header": {"stamp": n}, "percentage": 1.0 - n / 10, "status": "ok"},
            )
        )
        out.append(
            (
                "/rover/odom",
                ODOM,
                n * S + 1,
                {"position": {"x": float(n)}, "covariance": np.zeros(0)},
            )
        )
    return out


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    path = tmp_path / "run.bag"
    write_recording(path, "ros1", TYPES, rows())
    return path


def test_init_writes_a_model_that_match_and_monitor_take_as_it_is(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, bag: Path
) -> None:
    model = tmp_path / "model"  # made by init, as a new user names a new folder
    assert main(["init", "--source", str(bag), "--robot", "rover", str(model)]) == 0
    out = capsys.readouterr().out
    assert "RoverBatteryPercentage[rover]" in out and "number" in out
    assert "RoverOdomPositionX[rover]" in out
    assert "Header" not in out and "covariance" not in out  # the header, arrays: left out
    config = model / "rover.toml"
    formula = "always (RoverBatteryPercentage[rover] > 0.7)"
    assert main(["match", "--config", str(config), "--json", formula]) == 0
    (feature,) = json.loads(capsys.readouterr().out)["features"]
    assert [t["topic"] for t in feature["topics"]] == ["/rover/battery"]
    code = main(["monitor", "--config", str(config), "--source", str(bag), "--json", formula])
    verdicts = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert code == 1 and (verdicts[0]["verdict"], verdicts[0]["t"]) == (False, 3)
    # booleans and strings as the formulas use them
    km = KnowledgeManager.from_config(config)
    both = 'always (not RoverBatteryCharging[rover] and RoverBatteryStatus[rover] == "ok")'
    assert [getattr(e, "verdict", e) for e in km.monitor(both, bag)] == [True]


def test_init_takes_the_topics_chosen_and_writes_no_file_twice(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, bag: Path
) -> None:
    made = KnowledgeManager.init([bag], tmp_path, topics=["/rover/odom"])
    assert [f.name for f in made.features] == [
        "RoverOdomPositionX",
        "RoverOdomPositionY",
        "RoverOdomPositionZ",
    ]
    assert made.config == tmp_path / "robot.toml"
    assert main(["init", "--source", str(bag), str(tmp_path)]) == 2
    assert capsys.readouterr().err == (
        f"error: {tmp_path / 'robot.ttl'}: exists already (init writes new files only)\n"
    )
    # --topics A B DIR: the folder is no topic
    code = main(
        ["init", "--source", str(bag), "--robot", "r2", "--topics", "/rover/odom"]
        + ["/rover/battery", str(tmp_path)]
    )
    assert code == 0 and "RoverBatteryPercentage[r2]" in capsys.readouterr().out
    assert (
        main(["init", "--source", str(bag), "--robot", "r3", "--topics", "/nowhere", str(tmp_path)])
        == 2
    )
    assert "--topics /nowhere: in no recording" in capsys.readouterr().err


def test_several_files_after_one_option_are_taken_as_a_shell_glob_gives_them(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """`--msg A B FORMULA` (and `--source A B`, `-f A B`) as `--msg A --msg B FORMULA`."""
    from dkreason.cli.args import spread

    msgs = sorted((Path(__file__).parents[1] / "examples/traffic/msg").rglob("*.msg"))
    a, b = (str(m) for m in msgs[:2])
    assert spread(["monitor", "--msg", a, b, "--config", "c", "always (X[a] > 1)"]) == [
        "monitor", "--msg", a, "--msg", b, "--config", "c", "always (X[a] > 1)",
    ]  # fmt: skip
    assert spread(["monitor", "--source", "x.bag", "y.mcap", "always p"]) == [
        "monitor", "--source", "x.bag", "--source", "y.mcap", "always p",
    ]  # fmt: skip
    assert spread(["serve", "--source", "x.bag", "y.bag"]) == [
        "serve",
        "--source",
        "x.bag",
        "y.bag",
    ]
    bag = tmp_path / "run.bag"
    write_recording(bag, "ros1", CAR_TYPES, car_rows())
    config = Path(__file__).parents[1] / "examples" / "single.toml"
    code = main(["info", "--msg", a, b, "--json", str(bag)])
    assert code == 0 and json.loads(capsys.readouterr().out)["recordings"]
    code = main(["monitor", "--config", str(config), "--msg", a, b, "--source", str(bag), SPEEDING])
    assert code == 1 and "violated" in capsys.readouterr().out


def test_bare_dkreason_prints_usage(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([]) == 2
    out = capsys.readouterr().out
    assert out.startswith("usage: dkreason") and "init" in out and "completion" in out


@pytest.mark.parametrize("shell", ["bash", "zsh"])
def test_completion_scripts_complete_commands_options_and_actions(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, shell: str
) -> None:
    import shutil
    import subprocess

    assert main(["completion", shell]) == 0
    script = tmp_path / "completion.sh"
    script.write_text(capsys.readouterr().out)
    if shell == "zsh" or shutil.which("bash") is None:
        assert "complete -o filenames -F _dkreason dkreason" in script.read_text()
        return
    asked = (
        f"source {script}\n"
        'ask() { COMP_WORDS=("$@"); COMP_CWORD=$(($# - 1)); _dkreason; echo "${COMPREPLY[*]}"; }\n'
        "ask dkreason mon\nask dkreason monitor --rec\nask dkreason specs ad\n"
        "ask dkreason specs add --con\nask dkreason info --fie\n"
    )
    done = subprocess.run(["bash", "-c", asked], capture_output=True, text=True, check=True)
    assert done.stdout.splitlines() == ["monitor", "--record", "add", "--config", "--fields"]
