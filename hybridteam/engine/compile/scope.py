"""Names an agent's expressions can read, and the collector of a model's errors.

Every expression of an agent (guards, flows, inputs, actions, law bindings) is compiled
against one symbol table: its plant state, variables and parameters by column, ``t`` and
``t_in_mode``, and — in a transition triggered by a message — the message's fields. The
compiler modules share the table's construction and the :class:`Collector`, which gathers
every problem of a model instead of stopping at the first.
"""

from __future__ import annotations

from hybridteam.errors import DocPath, ModelError
from hybridteam.expr import Expression, ExpressionError, compile_expression
from hybridteam.expr.language import Reader


class Collector:
    """Collects every error of a model instead of stopping at the first, once per place.

    One place in a file can be compiled several times: a protocol's role body (its law,
    inputs and transitions) is compiled once for every region state that plays the role
    (Follow, Requesting, ... all play ``follow``). Its mistake is one mistake, so an error
    already collected at the same place with the same text is not collected again.
    """

    def __init__(self) -> None:
        self.errors: list[ModelError] = []
        self._seen: set[tuple] = set()

    def add(self, err: ModelError) -> None:
        """Collect ``err`` unless the same error at the same place is already collected."""
        key = (err.path, err.offset, str(err))
        if key not in self._seen:
            self._seen.add(key)
            self.errors.append(err)

    def expr(
        self, text: str | float, symbols, where: DocPath, *, condition: bool = False
    ) -> Expression | None:
        try:
            return compile_expression(str(text), symbols, condition=condition)
        except ExpressionError as exc:
            self.add(ModelError(where, exc.message, offset=exc.offset, hint=exc.hint))
            return None

    def fail(self, where: DocPath, message: str, hint: str | None = None) -> None:
        self.add(ModelError(where, message, hint=hint))


def symbols(
    state: dict[str, int], variables: dict[str, int], params: dict[str, int]
) -> dict[str, Reader]:
    """The readers of ``t``, ``t_in_mode`` and the agent's state, variables and parameters by
    column. The lambdas bind their column as a default argument (a closure over the loop
    variable would read the last column), which mypy cannot infer: hence the ignores."""
    syms = {
        "t": Reader(lambda c: c.t, lambda r: r.t),
        "t_in_mode": Reader(lambda c: c.t_in, lambda r: r.t_in),
    }
    for name, j in state.items():
        syms[name] = Reader(lambda c, j=j: c.x[:, j], lambda r, j=j: r.x[j])  # type: ignore[misc]  # default-bound lambda
    for name, j in variables.items():
        syms[name] = Reader(lambda c, j=j: c.v[:, j], lambda r, j=j: r.v[j])  # type: ignore[misc]  # default-bound lambda
    for name, j in params.items():
        syms[name] = Reader(lambda c, j=j: c.p[:, j], lambda r, j=j: r.p[j])  # type: ignore[misc]  # default-bound lambda
    return syms


def message_symbols(fields: set[str]) -> dict:
    """Names a transition triggered by a message can read: ``msg_sender`` (the sending
    agent's index), ``msg_sent`` (its send time) and ``msg_<field>`` for each field."""
    syms = {"msg_sender": lambda c: c.m["sender"], "msg_sent": lambda c: c.m["t_send"]}
    for f in sorted(fields):
        syms[f"msg_{f}"] = lambda c, f=f: c.m[f]  # type: ignore[misc]  # default-bound lambda
    return syms


def resolve_mode(
    name: str, paths: list[str], near: str | None = None
) -> tuple[int | None, list[str]]:
    """Index of the mode called ``name`` (a unique name or dotted-path suffix), and matches.

    Of several matches, the one sharing the longest enclosing scope with ``near`` (the
    transition's source) wins if it alone does: a mode library copied under two protocol
    roles (``Lead.Avoid``, ``Offering.Avoid``) still says ``to: Avoid`` inside each copy.
    """
    matches = [i for i, p in enumerate(paths) if p and (p == name or p.endswith("." + name))]
    if len(matches) > 1 and near is not None:

        def scope(i: int) -> int:
            a, b = paths[i].split(".")[:-1], near.split(".")
            k = 0
            while k < min(len(a), len(b)) and a[k] == b[k]:
                k += 1
            return k

        best = max(scope(i) for i in matches)
        nearest = [i for i in matches if scope(i) == best]
        if len(nearest) == 1:
            return nearest[0], [paths[i] for i in matches]
    return (matches[0] if len(matches) == 1 else None), [paths[i] for i in matches]
