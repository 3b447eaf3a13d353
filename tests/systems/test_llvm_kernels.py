"""A scene's functions written as LLVM IR (``systems.llvm_kernels``) compute what numba's
compile of the same expressions computes, for every function the scene language has, and
the drivers run them like numba's."""

import re

import numpy as np
import pytest

from systems import llvm_kernels
from systems.compiled import compile_system, system_code
from systems.mechanics import derive
from systems.scene import load_scene, parse_scene
from systems.simulation import run_to_end

POTENTIAL = (
    "k*(x**2/2 + tan(x/3) + atan2(y, 2) + sinh(x/4) + cosh(y/5) + asin(x/9) + acos(y/9)"
    " + atan(x) + exp(-y**2) + log(2 + x**2) + sqrt(1 + y**2) + abs(x)*y**3"
    " + (1 + x**2)**(3/2) + (2 + y**2)**(-1/2) + (3 + x**2)**1.7 + x**5/7 + 1/(4 + y**2)**3)"
)
EVERY_FUNCTION = f"""
[system]
coordinates = ["x", "y"]
parameters = {{ k = 1.5, c = 0.25 }}
kinetic = "(1 + c*cos(y)**2)*x_dot**2/2 + y_dot**2/2 + c*x_dot*y_dot*tanh(x)"
potential = "{POTENTIAL}"
[initial]
x = 0.4
y = -0.3
x_dot = 0.2
[drawing]
points = {{ a = ["sin(x)", "y*cos(x)"], b = ["exp(y/4)", "abs(x - y)"] }}
links = [["origin", "a"], ["a", "b"]]
"""

SEPARABLE = """
[system]
coordinates = ["x", "y"]
parameters = { k = 1.5 }
kinetic = "(x_dot**2 + y_dot**2)/2"
potential = "k*(x**4/4 + cosh(y/3) + atan2(x, 1 + y**2) + abs(y)**2.5)"
[initial]
x = 0.7
"""

WANTS = ("rhs", "hamiltonian", "velocities", "momenta", "lagrangian", "drawing")


def _states(compiled, count=40, seed=5):
    rng = np.random.default_rng(seed)
    y0 = compiled.initial_state()
    return y0 + rng.uniform(-1.5, 1.5, (count, len(y0)))


def _same(a, b):
    np.testing.assert_allclose(a, b, rtol=4e-16, atol=0.0, equal_nan=True)


def _hamiltonian_one_at_a_time(compiled, ts, Y):
    """H row by row through the scalar function (not ``pe_rows_hamiltonian``)."""
    return np.array(
        [
            compiled.kernels.hamiltonian(t, y, compiled.parameters)
            for t, y in zip(ts, Y, strict=True)
        ]
    )


@pytest.mark.parametrize("text", [EVERY_FUNCTION, SEPARABLE], ids=["every_function", "separable"])
def test_llvm_functions_equal_numbas(text):
    mechanics = derive(parse_scene(text))
    wants = WANTS if "drawing" in text else (*WANTS[:5], "separable")
    llvm = compile_system(mechanics, wants, backend="llvm")
    numba = compile_system(mechanics, wants, backend="numba")
    assert isinstance(llvm.kernels, llvm_kernels.LLVMKernels)
    Y = _states(llvm)
    n = llvm.n
    ts = np.linspace(0.0, 3.0, len(Y))
    for t, y in zip(ts, Y, strict=True):
        _same(llvm.rhs(t, y), numba.rhs(t, y))
    _same(_hamiltonian_one_at_a_time(llvm, ts, Y), numba.hamiltonian(ts, Y))
    _same(llvm.velocities(ts, Y), numba.velocities(ts, Y))
    _same(llvm.momenta(ts, Y[:, :n], Y[:, n:]), numba.momenta(ts, Y[:, :n], Y[:, n:]))
    if "drawing" in wants:
        _same(llvm.drawing(ts, Y), numba.drawing(ts, Y))
    else:
        P = llvm.parameters
        for y in Y:
            _same(llvm.kernels.kinetic(y, P), numba.kernels.kinetic(y, P))
            _same(llvm.kernels.potential(0.5, y, P), numba.kernels.potential(0.5, y, P))
            for name in ("grad_kinetic", "grad_potential"):
                a, b = np.empty(n), np.empty(n)
                args = (y, P) if name == "grad_kinetic" else (0.5, y, P)
                getattr(llvm.kernels, name)(*args, a)
                getattr(numba.kernels, name)(*args, b)
                _same(a, b)


@pytest.mark.parametrize("method", ["gauss_legendre6", "dop853", "rk4", "yoshida8"])
def test_runs_on_llvm_functions_equal_runs_on_numbas(method):
    text = SEPARABLE if method == "yoshida8" else EVERY_FUNCTION
    mechanics = derive(parse_scene(text))
    wants = ("rhs", "hamiltonian", "separable") if method == "yoshida8" else ("rhs", "hamiltonian")
    setting = {"tol": 1e-10} if method == "dop853" else {"dt": 0.01}
    ends = []
    for backend in ("llvm", "numba"):
        compiled = compile_system(mechanics, wants, backend=backend)
        _, last = run_to_end(compiled, method=method, t_end=0.5, **setting)
        assert last.status == "ok", last.message
        ends.append((last.steps, last.y[-1]))
    assert ends[0][0] == ends[1][0]
    _same(ends[0][1], ends[1][1])


@pytest.mark.parametrize("name", ["cartesian_pendulum", "rolling_disk", "bouncing_ball"])
def test_constrained_scenes_functions_equal_numbas(name):
    """A constrained scene's own functions (``constraints.PRIMITIVES``: the rows, the
    saddle-point system with its 2-D targets, gamma, ...) and what the drivers' generic
    multipliers, projection and impacts make of them."""
    mechanics = derive(load_scene(name))
    wants = ("rhs", "hamiltonian", "velocities")
    llvm = compile_system(mechanics, wants, backend="llvm")
    numba = compile_system(mechanics, wants, backend="numba")
    assert isinstance(llvm.kernels, llvm_kernels.LLVMKernels)
    Y = _states(llvm, count=10)
    k = int(llvm.constraint_functions()[-1][0])
    for t, y in zip(np.linspace(0.0, 1.0, len(Y)), Y, strict=True):
        _same(llvm.rhs(t, y), numba.rhs(t, y))
        a, b = np.empty(k), np.empty(k)
        llvm.constrained("c_multipliers", t, y, llvm.parameters, a)
        numba.constrained("c_multipliers", t, y, numba.parameters, b)
        _same(a, b)
    ends = []
    for compiled in (llvm, numba):
        _, last = run_to_end(compiled, method="constrained_dop853", t_end=1.0, tol=1e-10)
        assert last.status == "ok", last.message
        ends.append((last.steps, last.y[-1]))
    assert ends[0][0] == ends[1][0]
    _same(ends[0][1], ends[1][1])


def test_a_system_in_matrix_form_solves_for_its_velocities_as_numba_does():
    """A five-link chain: M(q) is left to the kernels, which solve M qdot = p - a with the
    drivers' ``solve_augmented`` (through its C wrapper) before the rest."""
    from systems.families import pendulum_chain

    mechanics = derive(parse_scene(pendulum_chain(5)))
    assert mechanics.matrix_form is not None
    wants = ("rhs", "hamiltonian", "velocities", "momenta", "drawing")
    llvm = compile_system(mechanics, wants, backend="llvm")
    numba = compile_system(mechanics, wants, backend="numba")
    Y = _states(llvm, count=20)
    ts = np.linspace(0.0, 1.0, len(Y))
    for t, y in zip(ts, Y, strict=True):
        _same(llvm.rhs(t, y), numba.rhs(t, y))
    _same(llvm.hamiltonian(ts, Y), numba.hamiltonian(ts, Y))
    _same(llvm.velocities(ts, Y), numba.velocities(ts, Y))
    _same(llvm.drawing(ts, Y), numba.drawing(ts, Y))
    ends = []
    for compiled in (llvm, numba):
        _, last = run_to_end(compiled, method="gauss_legendre6", t_end=0.5, dt=0.01)
        assert last.status == "ok", last.message
        ends.append(last.y[-1])
    _same(ends[0], ends[1])


def test_an_unknown_backend_is_refused():
    with pytest.raises(ValueError, match="backend must be one of"):
        compile_system(derive(load_scene("simple_pendulum")), ("rhs",), backend="gcc")


@pytest.mark.parametrize("name", ["double_pendulum", "rolling_disk", "chain"])
def test_code_written_in_a_worker_is_machine_code_here(name):
    """The symbolic half of a build (``systems.sources.build_code``) runs in a worker
    process; its IR names the drivers' solver instead of holding an address of that
    process, and loads here into functions equal to an in-process compile's."""
    from systems import processes
    from systems.compiled import load_system
    from systems.families import pendulum_chain
    from systems.sources import build_code, wants_for

    source = parse_scene(pendulum_chain(3)) if name == "chain" else load_scene(name)
    mechanics, code = processes.run(build_code, source, cpu_seconds=120.0)
    assert code.backend == "llvm"
    # no address as a constant (compose_stages turns its arguments into pointers)
    assert re.search(r"inttoptr \(?i64 -?\d", code.text) is None
    assert (llvm_kernels.SOLVER_SYMBOL in code.text) == (mechanics.matrix_form is not None)
    here = compile_system(mechanics, wants_for(mechanics), backend="numba")
    there = load_system(mechanics, code)
    Y = _states(here, count=10)
    ts = np.linspace(0.0, 1.0, len(Y))
    for t, y in zip(ts, Y, strict=True):
        _same(there.rhs(t, y), here.rhs(t, y))
    _same(there.hamiltonian(ts, Y), here.hamiltonian(ts, Y))


def test_the_written_code_is_remembered_per_scene(monkeypatch):
    """A scene opened again skips the writing: its IR comes from the disk cache, and so
    do its functions' names (no specification of them: symbolic work, 3 ms of the
    rolling disk's reopening)."""
    from systems.compiled import _KernelWriter, system_code

    # a scene of its own: another test of this process may have written the catalogue's
    mechanics = derive(parse_scene(SEPARABLE.replace("k = 1.5", "k = 1.625")))
    first = system_code(mechanics, ("rhs", "hamiltonian"))

    def refuse(*args):
        raise AssertionError("written again")

    monkeypatch.setattr(llvm_kernels, "write_ir", refuse)
    monkeypatch.setattr(_KernelWriter, "specs", refuse)
    again = system_code(mechanics, ("rhs", "hamiltonian"))
    assert again.text == first.text and again.names == first.names
    with pytest.raises(AssertionError, match="written again"):
        system_code(mechanics, ("rhs", "hamiltonian", "velocities"))


def test_machine_code_is_kept_and_loaded_again(monkeypatch, capfd):
    """A scene opened again loads its functions' machine code from disk; a damaged file
    is reported, compiled anew and replaced."""
    from systems.compiled import load_system, system_code
    from systems.families import pendulum_chain

    mechanics = derive(parse_scene(pendulum_chain(4)))
    code = system_code(mechanics, ("rhs", "hamiltonian"))
    kept = []
    keep = llvm_kernels._ObjectFile.keep
    monkeypatch.setattr(
        llvm_kernels._ObjectFile, "keep", lambda self, m, c: (kept.append(c), keep(self, m, c))
    )
    first = load_system(mechanics, code)
    path = llvm_kernels._ObjectFile(code.text).path
    assert path.exists()
    kept.clear()
    again = load_system(mechanics, code)
    assert kept == []  # loaded, not compiled
    Y = _states(first, count=8)
    ts = np.linspace(0.0, 1.0, len(Y))
    _same(again.hamiltonian(ts, Y), first.hamiltonian(ts, Y))
    path.write_bytes(path.read_bytes()[:-40] + b"\0" * 40)
    capfd.readouterr()
    repaired = load_system(mechanics, code)
    assert len(kept) == 1 and "machine-code" in capfd.readouterr().err
    _same(repaired.hamiltonian(ts, Y), first.hamiltonian(ts, Y))
    for t, y in zip(ts, Y, strict=True):
        _same(repaired.rhs(t, y), first.rhs(t, y))


DRIVEN = """
[system]
coordinates = ["x"]
parameters = { w = 1.3, a = 0.7 }
lagrangian = "x_dot**2/2 - (1 + a*cos(w*t))*x**2/2 - abs(x)**3/3"
[initial]
x = 0.5
"""


@pytest.mark.skipif(llvm_kernels._vector_library() is None, reason="no glibc vector math library")
@pytest.mark.parametrize("per_lane", [False, True], ids=["libmvec", "one_call_a_lane"])
@pytest.mark.parametrize("text", [EVERY_FUNCTION, DRIVEN], ids=["every_function", "driven"])
def test_h_over_rows_in_vector_registers_is_the_scalar_h_to_round_off(text, per_lane, monkeypatch):
    """``pe_rows_hamiltonian``: H of several rows at a time (glibc's vector sin, cos, ...;
    or, where the library lacks a function, the scalar one lane by lane), the last rows
    padded to a whole vector; any number of rows, a time per row or one for all. Each
    state's H is the same whatever batch it comes in."""
    if per_lane:  # a libmvec without any of the functions: the text and its key change
        monkeypatch.setattr(llvm_kernels, "_vector_library", lambda: frozenset())
    mechanics = derive(parse_scene(text))
    compiled = compile_system(mechanics, ("rhs", "hamiltonian"), backend="llvm")
    assert "hamiltonian" in compiled.kernels.rows
    assert ("_ZGV" in system_code(mechanics, ("hamiltonian",), backend="llvm").text) != per_lane
    lanes = llvm_kernels.vector_target()[1]
    Y = _states(compiled, count=5 * lanes + 3)
    ts = np.linspace(0.0, 7.0, len(Y))
    every = compiled.hamiltonian(ts, Y)
    one = _hamiltonian_one_at_a_time(compiled, ts, Y)
    np.testing.assert_allclose(every, one, rtol=1e-14, atol=1e-14 * np.max(np.abs(one)))
    for start, stop in ((0, 1), (3, 4), (0, lanes - 1), (1, lanes + 1), (2, 4 * lanes + 1)):
        np.testing.assert_array_equal(
            compiled.hamiltonian(ts[start:stop], Y[start:stop]), every[start:stop]
        )
    at = compiled.hamiltonian(2.5, Y)
    np.testing.assert_array_equal(at, [compiled.hamiltonian(2.5, y[None])[0] for y in Y])
    one = _hamiltonian_one_at_a_time(compiled, np.full(len(Y), 2.5), Y)
    np.testing.assert_allclose(at, one, rtol=1e-14, atol=1e-14 * np.max(np.abs(one)))
    assert compiled.hamiltonian(0.0, Y[:0]).shape == (0,)


def test_h_stays_one_row_at_a_time_in_matrix_form_and_without_functions_to_call():
    """H of a system in matrix form solves for the velocities first (a loop of the
    drivers); Hénon-Heiles' H is arithmetic alone, a few nanoseconds a row: neither is
    written over rows (compiling it would cost more than it saves)."""
    from systems.families import pendulum_chain

    chain = derive(parse_scene(pendulum_chain(5)))
    assert chain.matrix_form is not None
    for mechanics in (chain, derive(load_scene("henon_heiles"))):
        compiled = compile_system(mechanics, ("rhs", "hamiltonian"))
        assert isinstance(compiled.kernels, llvm_kernels.LLVMKernels)
        assert compiled.kernels.rows == {}
        Y = _states(compiled, count=19)
        ts = np.linspace(0.0, 1.0, len(Y))
        _same(compiled.hamiltonian(ts, Y), _hamiltonian_one_at_a_time(compiled, ts, Y))
