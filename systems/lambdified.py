"""Lambdified functions that cross between processes as their source text.

``sympy.lambdify`` makes a Python function by compiling source text it generates;
``pickle`` cannot send such a function (it pickles functions by module and name). The
symbolic work of the window runs in worker processes (``systems.processes``), and some of
what it makes is numeric functions the window evaluates afterwards (the constraint forces,
the Routhian's V_eff). ``lambdify`` here returns a ``Lambdified``: the same function, which
pickles as its source and the global names it uses (numpy's functions, by reference) and
is compiled from that text again where it is unpickled, without sympy.
"""

from __future__ import annotations

import importlib
import itertools
import linecache
import types
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import sympy

_counter = itertools.count(1)


@dataclass(frozen=True)
class _Module:
    """A module among a function's globals, pickled by name."""

    name: str


class Lambdified:
    """A function generated from source text (``sympy.lambdify``), picklable.

    Parameters
    ----------
    function : callable
        A function compiled from generated source, as ``sympy.lambdify`` returns it.
    source : str, optional
        Its source; by default read from ``linecache``, where ``sympy.lambdify`` puts it.

    Raises
    ------
    ValueError
        If the source of ``function`` cannot be found.
    """

    __slots__ = ("function", "source")

    def __init__(self, function: Callable, source: str | None = None):
        if source is None:
            source = "".join(linecache.getlines(function.__code__.co_filename))
        if not source:
            raise ValueError(f"no source text for {function.__name__!r}")
        self.function = function
        self.source = source

    def __call__(self, *args):
        return self.function(*args)

    def __reduce__(self):
        scope = self.function.__globals__
        namespace = {}
        for name in _global_names(self.function.__code__):
            if name in scope:
                value = scope[name]
                namespace[name] = (
                    _Module(value.__name__) if isinstance(value, types.ModuleType) else value
                )
        return (_compiled_again, (self.source, self.function.__name__, namespace))


def lambdify(args: Sequence, exprs, **options) -> Lambdified:
    """``sympy.lambdify(args, exprs, **options)`` as a picklable ``Lambdified``.

    ``modules="numpy"`` is given to sympy as the numpy module itself: the same printer
    and the same functions, but the name makes sympy run ``from numpy import *`` once
    per process, which imports numpy's lazily loaded submodules (f2py, testing, ...):
    0.07-0.1 s of ``derive``'s equilibrium search.
    """
    if isinstance(options.get("modules"), str) and options["modules"] == "numpy":
        import numpy

        options = {**options, "modules": [numpy]}
    return Lambdified(sympy.lambdify(args, exprs, **options))


def _global_names(code: types.CodeType) -> set[str]:
    """The names ``code`` and the code objects nested in it may look up."""
    names = set(code.co_names)
    for constant in code.co_consts:
        if isinstance(constant, types.CodeType):
            names |= _global_names(constant)
    return names


def _compiled_again(source: str, name: str, namespace: dict) -> Lambdified:
    """A ``Lambdified`` unpickled: its source compiled again with its globals."""
    scope = {
        key: importlib.import_module(value.name) if isinstance(value, _Module) else value
        for key, value in namespace.items()
    }
    filename = f"<lambdified-{next(_counter)}>"
    # kept in linecache, as sympy does, so that tracebacks show the line
    linecache.cache[filename] = (len(source), None, source.splitlines(True), filename)
    exec(compile(source, filename, "exec"), scope)  # noqa: S102 - our own generated code
    return Lambdified(scope[name], source)
