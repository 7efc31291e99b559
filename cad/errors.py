"""Project exceptions, all in one place.

They live in ``cad`` because ``cad`` is the root of the one-way import chain
(cad → mesh → fe → rsm → validation), so every stage can raise them.
"""

from __future__ import annotations


class HingelabError(Exception):
    """Base class of every error the project raises on purpose."""


class ParameterError(HingelabError, ValueError):
    """A parameter is outside its allowed range; the message names it, its value and the range.

    Attributes:
        parameter: The parameter the message starts with, as the code spells it (the
            dataclass field ``check_range`` names), or None. A boundary that knows what the
            user typed for it (a command-line option, a file key) words the message in the
            user's terms with ``renamed``.
    """

    def __init__(self, message: str, *, parameter: str | None = None) -> None:
        super().__init__(message)
        self.parameter = parameter

    def renamed(self, user_name: str) -> ParameterError:
        """Return this error naming ``user_name`` where it names ``parameter``.

        ``check_range("increments_per_stage", …)`` gives "increments_per_stage must be in
        [2, 10000], got 1"; renamed to ``--increments``: "--increments must be in [2, 10000],
        got 1". An error that does not start with its parameter is returned as it is.
        """
        text = str(self)
        if self.parameter is None or not text.startswith(self.parameter):
            return self
        return ParameterError(user_name + text[len(self.parameter) :], parameter=user_name)


class GeometryError(HingelabError, ValueError):
    """The CAD kernel produced or was asked for an impossible solid."""


class MeshQualityError(HingelabError, ValueError):
    """A mesh has an inverted or too distorted element, or a missing named set."""


class ConvergenceError(HingelabError, RuntimeError):
    """A nonlinear solve did not converge.

    Attributes:
        increment: Index of the load increment that failed.
        iteration: Last iteration reached.
        residual: Residual norm at that iteration.
        partial: Whatever the caller could keep (e.g. the partial loop), or None.
    """

    def __init__(
        self,
        message: str,
        *,
        increment: int,
        iteration: int,
        residual: float,
        partial: object | None = None,
    ) -> None:
        super().__init__(
            f"{message} (increment {increment}, iteration {iteration}, residual {residual:.3e})"
        )
        self.increment = increment
        self.iteration = iteration
        self.residual = residual
        self.partial = partial


class SolverError(HingelabError, RuntimeError):
    """A linear solver failed on a matrix it was given (e.g. not positive definite)."""


class ResourceError(HingelabError, MemoryError):
    """A computation would need more memory than the machine has; the message says how much."""


class DataError(HingelabError, ValueError):
    """Input data (a table or measurement file) is malformed; the message names file, row, column."""


class EffectError(DataError):
    """A user's effect (a file or a plug-in) failed a call, naming file, class and hook."""


def check_range(
    name: str, value: float, lo: float, hi: float, *, lo_open: bool = False, hi_open: bool = False
) -> None:
    """Raise ParameterError unless ``lo <= value <= hi`` (bounds optionally open).

    Args:
        name: Parameter name as the user spells it.
        value: Its value.
        lo: Lower bound.
        hi: Upper bound (``float('inf')`` for none).
        lo_open: Exclude ``lo`` itself.
        hi_open: Exclude ``hi`` itself.

    Raises:
        ParameterError: Naming the parameter, its value and the allowed range.
    """
    import math

    bad = not math.isfinite(value) if hi != float("inf") else math.isnan(value)
    bad = bad or (value <= lo if lo_open else value < lo)
    bad = bad or (value >= hi if hi_open else value > hi)
    if bad:
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        raise ParameterError(
            f"{name} must be in {left}{lo:g}, {hi:g}{right}, got {value!r}", parameter=name
        )
