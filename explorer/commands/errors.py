"""The error a user can cause from the command line, and the conversion to it."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager


class UserError(Exception):
    """A problem in what the user gave; the CLI prints it and exits with status 2."""


@contextmanager
def user_errors() -> Iterator[None]:
    """Turn the physics core's input errors (and ``systems.usage``'s checks of options)
    into ``UserError`` with their message."""
    from systems.expressions import ExpressionError
    from systems.mechanics import DerivationError
    from systems.scene import SceneError
    from systems.usage import UsageError

    try:
        yield
    except (SceneError, ExpressionError, DerivationError, UsageError) as exc:
        raise UserError(str(exc)) from exc
