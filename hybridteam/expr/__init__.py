"""Safe, vectorized expressions for guards, invariants, flows, inputs and assignments.

:mod:`.language` defines the language and its compiled forms; :mod:`.compiler` turns text
into them. User text is only ever parsed, never executed.
"""

from hybridteam.expr.compiler import compile_assignment, compile_expression, free_names
from hybridteam.expr.language import (
    CONSTANTS,
    FUNCTIONS,
    Atom,
    Expression,
    ExpressionError,
    Getter,
    ModeTest,
)

__all__ = [
    "CONSTANTS",
    "FUNCTIONS",
    "Atom",
    "Expression",
    "ExpressionError",
    "Getter",
    "ModeTest",
    "compile_assignment",
    "compile_expression",
    "free_names",
]
