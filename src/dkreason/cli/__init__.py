"""`dkreason`: a thin CLI over KnowledgeManager.  Every DkError is one line on stderr, exit 2.

Arguments are parsed (cli/parser.py), one façade call is made by the command's module
(knowledge, monitoring, live), and the result rendered (cli/render.py).
"""

from __future__ import annotations

import importlib
import os
import sys
from collections.abc import Sequence

from ..errors import DkError, one_line
from .args import spread
from .parser import build


def main(argv: Sequence[str] | None = None) -> int:
    given = sys.argv[1:] if argv is None else list(argv)
    if not given:  # bare `dkreason`: what it can do
        build(__doc__.split("\n")[0] if __doc__ else None).print_help()
        return 2
    args = build(__doc__.split("\n")[0] if __doc__ else None).parse_args(spread(given))
    module, function = args.run.split(":")
    try:
        run = getattr(importlib.import_module(f".{module}", __name__), function)
        code: int = run(args)
        sys.stdout.flush()
        return code
    except DkError as exc:
        print(f"error: {one_line(str(exc))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # the reader went away (`| head`): stop quietly, as ROS tools do
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
