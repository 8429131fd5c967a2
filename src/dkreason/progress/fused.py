"""Generated code for the shapes monitors run most: one Python function per formula.

    always S                                   (an invariant over a state formula S)
    always (A -> eventually[a, b] B)           (response; also `not A or …`, A = true, and
    always not always[a, b] S ≡ always eventually[a, b] not S)

A, B and S are temporal-free.  The generated step reads its features once, evaluates them on a
two-valued fast path when all are known (Kleene otherwise), and keeps the response's waiting
positions in a deque: a B at time t settles every waiting position whose window holds t, and a
window closes at the state reaching its end — the same decisions as the general engine
(nodes.py), checked against the same offline semantics in the tests, several times faster.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ..parse.formula import ANY, BoolConst, Connective, Formula, Not, Temporal
from .compile import exact
from .nodes import Time, Why, fmt
from .state import _boolean_keys, _py, evaluate, features, is_state, render

TRUE = BoolConst(True)


@dataclass(frozen=True, slots=True)
class Shape:
    kind: str  # "invariant" | "response"
    a: Formula  # trigger (response) or the invariant itself
    b: Formula | None = None
    lo: Time = 0
    hi: Time | None = None


def shape(f: Formula) -> Shape | None:
    """The fused shape of a (quantifier-free) formula, if it has one."""
    if not (isinstance(f, Temporal) and f.op == "always" and f.interval == ANY):
        return None
    body = f.arg
    if is_state(body):
        return Shape("invariant", body)
    trigger: Formula = TRUE
    if isinstance(body, Connective) and body.op in ("->", "or") and is_state(body.left):
        trigger = body.left if body.op == "->" else Not(body.left)
        body = body.right
    if isinstance(body, Not) and isinstance(body.arg, Temporal) and body.arg.op == "always" \
            and is_state(body.arg.arg):
        body = Temporal("eventually", body.arg.interval, Not(body.arg.arg))
    if isinstance(body, Temporal) and body.op == "eventually" and is_state(body.arg):
        lo, hi = exact(body.interval.lo), exact(body.interval.hi)
        assert lo is not None
        return Shape("response", trigger, body.arg, lo, hi)
    return None


class Fused:
    """A formula compiled to one generated step function.

    `on_false(time, why)` and `on_unknown()` are called by the generated code; `finish()`
    settles what the end of the stream leaves open."""

    def __init__(self, s: Shape, on_false: Callable[[Why], None],
                 on_unknown: Callable[[list[str], Any], None]) -> None:
        self.shape = s
        self.pending: deque[list[Any]] = deque()
        self.unknown = False
        self._on_false, self._on_unknown = on_false, on_unknown
        self.step = _generate(s, self)

    # called from generated code -----------------------------------------------------
    def fail_now(self, t: Time, values: dict[str, Any]) -> None:
        s = self.shape
        shown = ", ".join(f"{k} = {values[k]}" for k in features(s.a))
        self._on_false(Why(render(s.a), t, f"was false at {fmt(t)}" +
                           (f" ({shown})" if shown else "")))

    def expire(self, ti: Time, weak: bool) -> None:
        if weak:
            self.unknown = True
            return
        s = self.shape
        assert s.b is not None
        within = f"[{fmt(ti + s.lo)}, {fmt(None if s.hi is None else ti + s.hi)}]"
        if isinstance(s.b, Not):
            text, detail = render(s.b.arg), f"held throughout {within}"
        else:
            text, detail = render(s.b), f"never held within {within}"
        if s.a != TRUE:
            text = f"{render(s.a)} held at {fmt(ti)}, but {text}"
        self._on_false(Why(text, ti, detail))

    def note_unknown(self, values: dict[str, Any], keys: list[str]) -> None:
        self._on_unknown([k for k in keys if values[k] is None], values)

    def finish(self) -> bool | None:
        """The verdict at the end of the stream (False also reported through on_false)."""
        while self.pending:
            ti, weak = self.pending.popleft()
            if not weak:
                self.expire(ti, weak)
                return False
            self.unknown = True
        return None if self.unknown else True


def _evaluation(f: Formula, var: str, names: dict[str, str], consts: list[Formula],
                indent: str) -> str:
    """Code assigning f's Kleene value to `var`: fast two-valued path, slow fallback."""
    mine = features(f)
    bools = _boolean_keys(f)
    known = " and ".join(f"type({names[k]}) is bool" if k in bools else f"{names[k]} is not None"
                         for k in mine) or "True"
    return (f"{indent}if {known}:\n{indent}    {var} = {_py(f, names)}\n"
            f"{indent}else:\n{indent}    {var} = slow(consts[{len(consts)}], v, t)\n"
            f"{indent}    self.note_unknown(v, {mine!r})\n")


def _generate(s: Shape, self: Fused) -> Callable[[Time, dict[str, Any]], bool]:
    """Source for `step(t, v) -> still running?`, compiled once per formula."""
    keys = features(s.a) + [k for k in (features(s.b) if s.b is not None else [])
                            if k not in features(s.a)]
    names = {k: f"x{i}" for i, k in enumerate(keys)}
    consts: list[Formula] = []

    def evaluation(f: Formula, var: str) -> str:
        code = _evaluation(f, var, names, consts, "    ")
        consts.append(f)
        return code

    reads = "".join(f"    {names[k]} = v[{k!r}]\n" for k in keys)
    lines = [f"def step(t, v):\n{reads}"]
    if s.kind == "invariant":
        mine = features(s.a)
        bools = _boolean_keys(s.a)
        known = " and ".join(f"type({names[k]}) is bool" if k in bools else
                             f"{names[k]} is not None" for k in mine) or "True"
        lines.append(f"""    if {known}:
        if {_py(s.a, names)}:
            return True
        self.fail_now(t, v)
        return False
    r = slow(consts[0], v, t)
    self.note_unknown(v, {mine!r})
    if r is False:
        self.fail_now(t, v)
        return False
    if r is None:
        self.unknown = True
    return True
""")
        consts.append(s.a)
    else:
        assert s.b is not None
        lo, hi = s.lo, s.hi
        lines.append(evaluation(s.b, "b"))
        expired = "False" if hi is None else f"t - e[0] > {hi!r}"
        ends_now = "False" if hi is None else f"e[0] + {hi!r} <= t"
        lines.append(f"""    pending = self.pending
    while pending:
        e = pending[0]
        if {expired}:
            pending.popleft()
            if not e[1]:
                self.expire(e[0], False)
                return False
            self.unknown = True
            continue
        break
    if pending and b is not False:
        if b is True:
            while pending and pending[0][0] <= t - {lo!r}:
                pending.popleft()
        else:
            for e in pending:
                if e[0] > t - {lo!r}:
                    break
                e[1] = True
    while pending:
        e = pending[0]
        if {ends_now}:
            pending.popleft()
            if not e[1]:
                self.expire(e[0], False)
                return False
            self.unknown = True
            continue
        break
""")
        if s.a == TRUE:
            lines.append("    a = True\n")
        else:
            lines.append(evaluation(s.a, "a"))
        now_satisfies = "b is True" if lo == 0 else "False"
        closes_now = "True" if hi == 0 else "False"
        lines.append(f"""    if a is not False and not ({now_satisfies}):
        weak = a is None or ({'b is None' if lo == 0 else 'False'})
        if {closes_now}:
            if not weak:
                self.expire(t, False)
                return False
            self.unknown = True
        else:
            pending.append([t, weak])
    return True
""")
    source = "".join(lines)
    scope: dict[str, Any] = {"self": self, "slow": evaluate, "consts": consts}
    exec(compile(source, f"<fused {s.kind}>", "exec"), scope)  # noqa: S102 - our own code
    step: Callable[[Time, dict[str, Any]], bool] = scope["step"]
    return step
