"""`dkreason info`: what recordings hold, with `--fields` every field path a spec can read."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dkreason import KnowledgeManager
from dkreason.cli import main
from dkreason.stream.recording import write_recording

SCAN = "x/msg/Scan"
TYPES = {
    SCAN: "std_msgs/Header header\nfloat32[] ranges\nfloat64[4] quad\nbool ok\nstring mode\n"
    "geometry_msgs/Point[] points\n",
}
ROWS = [
    (
        "/scan",
        SCAN,
        n * 10**8,
        {
            "ranges": np.ones(2, np.float32),
            "quad": np.zeros(4),
            "ok": True,
            "mode": "a",
            "points": [],
        },
    )
    for n in range(3)
]
WANT = [
    ("msg.header.stamp.sec", "int32"),
    ("msg.header.stamp.nanosec", "uint32"),
    ("msg.header.frame_id", "string"),
    ("msg.ranges[i]", "float32"),
    ("msg.quad[0..3]", "float64"),
    ("msg.ok", "bool"),
    ("msg.mode", "string"),
    ("msg.points[i].x", "float64"),
    ("msg.points[i].y", "float64"),
    ("msg.points[i].z", "float64"),
]


def info(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, Any, str]:
    code = main(["info", *args])
    out = capsys.readouterr()
    return code, json.loads(out.out) if "--json" in args and code == 0 else out.out, out.err


@pytest.mark.parametrize("fmt,name", [("ros1", "r.bag"), ("bare-mcap", "r.mcap"), ("sqlite3", "r")])
def test_fields_lists_every_path_a_spec_reads_with_its_type(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, fmt: str, name: str
) -> None:
    path = tmp_path / name
    write_recording(path, fmt, TYPES, ROWS)  # type: ignore[arg-type]
    if fmt == "sqlite3":  # a .db3 file itself
        (path,) = path.glob("*.db3")
    code, doc, _ = info(capsys, "--fields", "--json", str(path))
    (topic,) = doc["recordings"][0]["topics"]
    header = [] if fmt != "ros1" else [("msg.header.seq", "uint32")]
    want = header + WANT
    assert [(f["field"], f["type"]) for f in topic["fields"]] == want
    assert {f["kind"] for f in topic["fields"]} == {"number", "bool", "string"}
    code, text, _ = info(capsys, "--fields", str(path))
    assert code == 0 and "      msg.ranges[i]" in text and "float32" in text
    # what info lists, a spec reads
    assert KnowledgeManager.describe([path], fields=True)[0].topics[0].fields[-1].path == (
        "msg.points[i].z"
    )


def test_a_folder_of_recordings_is_read_as_each_of_them(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    runs = tmp_path / "runs"
    runs.mkdir()
    write_recording(runs / "a.mcap", "bare-mcap", TYPES, ROWS)
    write_recording(runs / "b.bag", "ros1", TYPES, ROWS[:2])
    write_recording(runs / "c", "mcap", TYPES, ROWS[:1])  # a ROS 2 bag folder: one recording
    code, doc, _ = info(capsys, "--json", str(runs))
    assert code == 0
    assert [(Path(r["recording"]).name, r["topics"][0]["count"]) for r in doc["recordings"]] == [
        ("a.mcap", 3),
        ("b.bag", 2),
        ("c", 1),
    ]
    (tmp_path / "empty").mkdir()
    code, _, err = info(capsys, str(tmp_path / "empty"))
    assert code == 2 and err.startswith(f"error: {tmp_path / 'empty'}: no recording in this folder")
