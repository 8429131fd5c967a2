"""Opening a Zenoh session, and how its callbacks are run: what every live command shares,
whichever protocol it then speaks (the federation's, wire.py; ROS 2's, rmw.py)."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

from ..errors import DkError
from ..inputs.files import read_text

ENDPOINT = re.compile(r"^[a-z][a-z0-9+-]*/\S+$")


def open_session(connect: list[str], listen: list[str], config_file: str | None = None) -> Any:
    """A peer session on explicit endpoints; multicast scouting is off, so only the endpoints
    given (and peers they know) are reached.  A Zenoh config file may set the rest (TLS,
    access control)."""
    import zenoh

    for endpoint in (*connect, *listen):
        if not ENDPOINT.match(endpoint):
            raise DkError(
                f"zenoh: bad endpoint {endpoint!r} (expected <protocol>/<address>, "
                f"e.g. tcp/192.168.1.10:7447)"
            )
    text = read_text(Path(config_file)) if config_file else None
    try:
        config = zenoh.Config.from_json5(text) if text is not None else zenoh.Config()
        config.insert_json5("mode", '"peer"')
        config.insert_json5("scouting/multicast/enabled", "false")
        config.insert_json5("connect/endpoints", json.dumps(connect))
        config.insert_json5("listen/endpoints", json.dumps(listen))
        return zenoh.open(config)
    except zenoh.ZError as exc:
        why = _zenoh_error(str(exc), config_file)
        raise DkError(
            f"zenoh: cannot open a session (connect {connect}, listen {listen}"
            f"{', config ' + config_file if config_file else ''}): {why}"
        ) from None


def _zenoh_error(text: str, config_file: str | None) -> str:
    """Zenoh's error text in one line: a JSON5 syntax error as `line:column: expected …`."""
    where = re.match(r"\s*-->\s*(\d+:\d+)", text)
    expected = re.search(r"=\s*(.+)\s*$", text)
    if where and expected:
        return f"{config_file}:{where.group(1)}: {expected.group(1)}"
    return (text.split(" at /")[0].strip().splitlines() or [""])[0][:300]


def direct(callback: Any) -> Any:
    """A callback zenoh calls on its own receiving task (zenoh-python's default hands each
    subscriber's samples to a thread of its own): samples of one session then reach the
    monitor in the order they were put, across keys (a ROS 2 message is never taken before the
    /clock tick put ahead of it), with no thread hop per sample.  It must only enqueue."""
    import zenoh

    return zenoh.handlers.Callback(callback, indirect=False)
