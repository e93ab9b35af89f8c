"""Generated code in every target language computes what the JAX lowering computes.

For the 2R arm, the hopping leg and the Panda (fingers locked), mass_matrix, gravity_torques,
inverse_dynamics, coriolis_matrix and forward_kinematics (and external_torques, with its n_ee x 6 wrench
argument, for the arm) are generated for each target and evaluated on random states with the default
parameters; every result must match ``jaxskid.lower`` (itself checked against Pinocchio in other tests) to
1e-10 relative. C and C++ are compiled with ``-Wall -Wextra -Werror -pedantic`` and run through a small
driver; Cython is built with its generated build script and imported; the NumPy module is imported; the
Matlab files run in GNU Octave; the Julia module, for which no interpreter is installed, is parsed by a
checker of the grammar the emitter writes and evaluated by that checker (see ``JuliaChecker``); the LaTeX
document is checked for balanced structure (and compiled when pdflatex exists). The native single-call
path is in ``test_native.py``.
"""

from __future__ import annotations

import importlib.util
import math
import re
import shutil
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxskid
from helpers import load
from jaxskid import codegen

QUANTITIES = ["mass_matrix", "gravity_torques", "inverse_dynamics", "forward_dynamics", "coriolis_matrix",
              "forward_kinematics"]
N_STATES = 3
RTOL = 1e-10
CFLAGS = ["-Wall", "-Wextra", "-Werror", "-pedantic", "-O1"]


class Case:
    """One robot: its equations, JAX reference values on random states, and all targets generated."""

    def __init__(self, name: str, out: Path):
        self.name = name
        self.robot = load(name)
        self.names = QUANTITIES + (["external_torques"] if name == "arm_2r" else [])
        self.eqs = jaxskid.derive(self.robot, self.names)
        self.names = list(self.eqs.quantities)  # the canonical order, which the generated files follow
        self.dyn = jaxskid.lower(self.eqs)  # the same equations the other targets print
        self.stem = codegen.stem(self.robot.name)
        self.out = out
        rng = np.random.default_rng(7)
        n, n_ee = self.robot.n_dof, len(self.robot.end_effectors)
        self.states = []
        for _ in range(N_STATES):
            self.states.append({
                "q": rng.uniform(-np.pi, np.pi, n), "qd": rng.uniform(-2, 2, n), "qdd": rng.uniform(-2, 2, n),
                "tau": rng.uniform(-5, 5, n), "wrench": rng.uniform(-1, 1, (n_ee, 6)),
            })
        self.params = np.array([self.robot.default_params()[k] for k in self.eqs.parameters])
        self.ref = {name: list(self.jax(name)) for name in self.names}
        self.files: dict[str, list[Path]] = {}

    def generate(self) -> None:
        """Write every target into ``out``; ``files`` lists the paths of each."""
        layout = codegen.Layout(self.eqs, tuple(self.names))  # shared by the targets that name symbols alike
        self.files = {t: codegen.write(codegen.emit(layout, t), self.out) for t in codegen.TARGETS}

    def args(self, name: str) -> tuple[str, ...]:
        return self.eqs.quantities[name].args

    def jax(self, name: str) -> np.ndarray:
        """The lowered JAX function at every state, mapped and run op by op: the same code as the jitted one,
        without its compile time (jit-compiling the Panda's 49-output Coriolis matrix alone takes about 10 s;
        its ops one by one, for the states together, well under one)."""
        p = self.dyn.param_vector()
        args = [jnp.asarray(np.stack([s[a] for s in self.states])) for a in self.args(name)]
        with jax.disable_jit():  # raw functions are jitted: run them op by op all the same
            return np.asarray(jax.vmap(self.dyn.raw(name), in_axes=(*[0] * len(args), None))(*args, p))


def close(got, ref, what: str) -> None:
    got, ref = np.asarray(got, dtype=float), np.asarray(ref, dtype=float)
    assert got.shape == ref.shape, f"{what}: shape {got.shape}, expected {ref.shape}"
    err = np.max(np.abs(got - ref)) / max(np.max(np.abs(ref)), 1e-300)
    assert err <= RTOL, f"{what}: relative error {err:.3g}"


@pytest.fixture(scope="module", params=["arm_2r", "hopping_leg"])
def case(request, tmp_path_factory):
    case = Case(request.param, tmp_path_factory.mktemp(f"gen-{request.param}"))
    case.generate()
    return case


# ------------------------------------------------------------------------------------------ Python
def _import(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_numpy_module(case):
    mod = _import(case.out / f"{case.stem}_numpy.py", f"gen_{case.stem}_numpy")
    assert mod.PARAMETERS == tuple(case.eqs.parameters)
    np.testing.assert_array_equal(mod.DEFAULT_PARAMS, case.params)
    for name in case.names:
        fn = getattr(mod, name)
        for s, state, ref in zip(range(N_STATES), case.states, case.ref[name]):
            close(fn(*(state[a] for a in case.args(name))), ref, f"{name} state {s}")
        # a batch with leading axes, evaluated at once, and explicit parameters
        batch = [np.stack([st[a] for st in case.states]) for a in case.args(name)]
        close(fn(*batch, case.params), np.stack(case.ref[name]), f"{name} batch")


def test_jax_target_is_the_lowered_module(case):
    (path,) = case.files["jax"]
    before, module, trailer = case.dyn.source.partition(path.read_text())
    assert not before and module, "the cache entry is the module followed by its key and checksum lines"
    # between them, the C of the native kernels (matrix-valued quantities, the backward step of forward dynamics)
    lines = [line for line in trailer.splitlines() if line and not line.startswith("NATIVE_C = (")]
    assert [line.split(":")[0] for line in lines] == ["# jaxskid-key", "# jaxskid-checksum"]
    ns: dict = {}
    exec(compile(path.read_text(), str(path), "exec"), ns)
    state = case.states[0]
    close(ns["inverse_dynamics"](state["q"], state["qd"], state["qdd"], case.params), case.ref["inverse_dynamics"][0],
          "jax module")


# ------------------------------------------------------------------------------------------ C and C++
def _driver(case, cxx: bool) -> str:
    """A main() that reads every quantity's inputs from stdin and prints its outputs, one per line."""
    s = case.stem
    lines = ["#include <stdio.h>", f'#include "{s}.h"', "", "static void read(double *x, int n)", "{",
             "    for (int i = 0; i < n; ++i) {", '        if (scanf("%lf", &x[i]) != 1) { x[i] = 0.0; }',
             "    }", "}", "", "int main(void)", "{"]
    if cxx:
        lines = ["#include <array>", "#include <cstdio>", "#include <iostream>", f'#include "{s}.hpp"', "",
                 "template <std::size_t N> static std::array<double, N> read()", "{", "    std::array<double, N> x{};",
                 "    for (auto &v : x) { std::cin >> v; }", "    return x;", "}", "", "int main()", "{"]
    layout = codegen.Layout(case.eqs, tuple(case.names))
    for k in layout.programs:
        sizes = {a: layout.arg_size(a) for a in (*k.args, "p")}
        lines.append(f"    for (int s = 0; s < {N_STATES}; ++s) {{")
        if cxx:
            for a in (*k.args, "p"):
                lines.append(f"        const auto {a} = read<{sizes[a]}>();")
            lines.append(f"        const auto out = {s}::{k.name}({', '.join((*k.args, 'p'))});")
        else:
            for a in (*k.args, "p"):
                lines += [f"        double {a}[{max(sizes[a], 1)}];", f"        read({a}, {sizes[a]});"]
            lines += [f"        double out[{k.size}];", f"        {s}_{k.name}({', '.join((*k.args, 'p'))}, out);"]
        lines += [f"        for (int i = 0; i < {k.size}; ++i) {{ printf(\"%.17g\\n\", out[i]); }}", "    }"]
    lines += ["    return 0;", "}", ""]
    return "\n".join(lines)


def _driver_input(case) -> str:
    values = []
    for name in case.names:
        for state in case.states:
            for a in case.args(name):
                values.extend(np.ravel(state[a]))
            values.extend(case.params)
    return "\n".join(f"{v:.17g}" for v in values) + "\n"


def _check_driver_output(case, text: str) -> None:
    values = np.array([float(v) for v in text.split()])
    i = 0
    for name in case.names:
        for s, ref in enumerate(case.ref[name]):
            close(values[i:i + ref.size].reshape(ref.shape), ref, f"{name} state {s}")
            i += ref.size
    assert i == values.size


@pytest.mark.parametrize("lang", ["c", "cpp"])
def test_c_and_cpp_compile_cleanly_and_match(case, lang, tmp_path):
    cxx = lang == "cpp"
    compiler = "g++" if cxx else "gcc"
    assert shutil.which(compiler), f"{compiler} is required"
    src = case.out / f"{case.stem}.{'cpp' if cxx else 'c'}"
    driver = tmp_path / f"driver.{'cpp' if cxx else 'c'}"
    driver.write_text(_driver(case, cxx))
    exe = tmp_path / "driver"
    std = "-std=c++17" if cxx else "-std=c99"
    proc = subprocess.run([compiler, std, *CFLAGS, f"-I{case.out}", "-o", str(exe), str(driver), str(src), "-lm"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    run = subprocess.run([str(exe)], input=_driver_input(case), capture_output=True, text=True, check=True)
    _check_driver_output(case, run.stdout)


def test_c_without_symbolic_parameters(tmp_path):
    """With every parameter replaced by its value there is no p array; the code must still compile."""
    robot = load("arm_2r")
    dyn = jaxskid.lower(robot, ["inverse_dynamics", "mass_matrix"], symbolic=[])
    eqs = jaxskid.derive(robot.substitute(list(robot.parameters)), ["inverse_dynamics", "mass_matrix"])
    assert eqs.parameters == ()
    codegen.generate(eqs, "c", tmp_path, names=["inverse_dynamics"])
    header = (tmp_path / "arm_2r.h").read_text()
    assert "#define ARM_2R_N_PARAMS 0" in header and "default_params" not in header.split("#define ARM_2R_N_DOF")[1]
    driver = tmp_path / "main.c"
    driver.write_text('#include <stdio.h>\n#include "arm_2r.h"\nint main(void)\n{\n'
                      "    const double q[2] = {0.3, -1.1}, qd[2] = {0.5, 2.0}, qdd[2] = {-1.0, 0.25};\n"
                      "    double out[2];\n    arm_2r_inverse_dynamics(q, qd, qdd, NULL, out);\n"
                      '    printf("%.17g %.17g\\n", out[0], out[1]);\n    return 0;\n}\n')
    subprocess.run(["gcc", "-std=c99", *CFLAGS, "-o", str(tmp_path / "main"), str(driver),
                    str(tmp_path / "arm_2r.c"), "-lm"], check=True, capture_output=True)
    out = subprocess.run([str(tmp_path / "main")], capture_output=True, text=True, check=True).stdout.split()
    close([float(v) for v in out], dyn.inverse_dynamics(np.array([0.3, -1.1]), np.array([0.5, 2.0]),
                                                        np.array([-1.0, 0.25])), "no parameters")


# ------------------------------------------------------------------------------------------ Cython
@pytest.mark.slow
def test_cython_builds_and_matches(case, tmp_path):
    for f in case.files["cython"]:
        shutil.copy(f, tmp_path)
    proc = subprocess.run([sys.executable, f"build_{case.stem}_cython.py"], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (so,) = tmp_path.glob(f"{case.stem}_cython*.so")
    mod = _import(so, f"{case.stem}_cython")
    np.testing.assert_array_equal(mod.DEFAULT_PARAMS, case.params)
    for name in case.names:
        for s, (state, ref) in enumerate(zip(case.states, case.ref[name])):
            close(getattr(mod, name)(*(state[a] for a in case.args(name))), ref, f"{name} state {s}")
    with pytest.raises(ValueError, match="expected shape"):
        mod.inverse_dynamics(np.zeros(case.robot.n_dof + 1), np.zeros(case.robot.n_dof), np.zeros(case.robot.n_dof))


# ------------------------------------------------------------------------------------------ Matlab/Octave
def _octave_vector(x) -> str:
    x = np.asarray(x)
    if x.ndim == 2:
        return "[" + "; ".join(" ".join(f"{v:.17g}" for v in row) for row in x) + "]"
    return "[" + "; ".join(f"{v:.17g}" for v in x) + "]"


def test_matlab_runs_in_octave(case, tmp_path):
    octave = shutil.which("octave-cli") or shutil.which("octave")
    assert octave, "GNU Octave is required: apt-get install -y --no-install-recommends octave"
    script = [f"addpath('{case.out}');"]
    for name in case.names:
        for s, state in enumerate(case.states):
            args = [_octave_vector(state[a]) for a in case.args(name)]
            if s > 0:  # the first state relies on the default parameters, the others pass them
                args.append(_octave_vector(case.params))
            script += [f"out = {case.stem}_{name}({', '.join(args)});",
                       "fprintf('%.17g\\n', permute(out, ndims(out):-1:1));"]
    (tmp_path / "check.m").write_text("\n".join(script) + "\n")
    proc = subprocess.run([octave, "--no-gui", "--norc", "--quiet", "--no-window-system", str(tmp_path / "check.m")],
                          capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    _check_driver_output(case, proc.stdout)


# ------------------------------------------------------------------------------------------ Julia
class JuliaChecker:
    """Parses the Julia the emitter writes, line by line against its grammar, and evaluates it.

    Every line must be one of the forms below; every ``function`` needs its ``end`` and the module its
    closing ``end``; expressions are parsed by a precedence-climbing parser (Julia's precedences:
    ``+ -`` < ``* / .* ./`` < unary ``-`` < ``^ .^``, right-associative ``^``), may call only Base math
    functions, and may use only names defined earlier in the function. Evaluating the parsed function
    (1-based indexing) on numbers is what proves the file computes the right values.
    """

    FUNCTIONS = {"sin": math.sin, "cos": math.cos, "tan": math.tan, "sqrt": math.sqrt, "exp": math.exp,
                 "log": math.log, "abs": abs}
    TOKEN = re.compile(r"\s*(?:(\d+\.\d*(?:e[+-]?\d+)?|\d+e[+-]?\d+|\d+)|([A-Za-z_][A-Za-z0-9_]*)|(\.\*|\./|\.\^|[-+*/^(),]))")
    IDENT = r"[A-Za-z_][A-Za-z0-9_]*"

    def __init__(self, text: str):
        self.functions: dict[str, tuple[list[str], list[tuple]]] = {}
        self.consts: dict[str, object] = {}
        self.parse(text.splitlines())

    # -- expressions
    def tokens(self, text: str) -> list[str]:
        out, pos = [], 0
        text = text.rstrip()
        while pos < len(text):
            m = self.TOKEN.match(text, pos)
            assert m and m.end() > pos, f"cannot tokenize {text[pos:pos + 30]!r}"
            out.append(m.group(m.lastindex))
            pos = m.end()
        return out

    def expression(self, text: str, defined: set):
        toks = self.tokens(text)
        tree, rest = self._binary(toks, 0, defined)
        assert not rest, f"trailing tokens {rest[:5]} in {text[:60]!r}"
        return tree

    _PREC = {"+": 1, "-": 1, "*": 2, "/": 2, ".*": 2, "./": 2, "^": 4, ".^": 4}

    def _binary(self, toks, min_prec, defined):
        lhs, toks = self._unary(toks, defined)
        while toks and toks[0] in self._PREC and self._PREC[toks[0]] >= min_prec:
            op = toks[0]
            prec = self._PREC[op]
            rhs, toks = self._binary(toks[1:], prec if op in ("^", ".^") else prec + 1, defined)
            lhs = (op.lstrip("."), lhs, rhs)
        return lhs, toks

    def _unary(self, toks, defined):
        assert toks, "expression ends early"
        if toks[0] in ("-", "+"):
            operand, rest = self._binary(toks[1:], 3, defined)
            return ("neg" if toks[0] == "-" else "pos", operand), rest
        return self._atom(toks, defined)

    def _atom(self, toks, defined):
        t, rest = toks[0], toks[1:]
        if t == "(":
            inner, rest = self._binary(rest, 0, defined)
            assert rest and rest[0] == ")", "unbalanced parenthesis"
            return inner, rest[1:]
        if re.fullmatch(r"[\d.]+(e[+-]?\d+)?", t):
            return ("num", float(t)), rest
        assert re.fullmatch(self.IDENT, t), f"unexpected token {t!r}"
        if rest and rest[0] == "(":
            assert t in self.FUNCTIONS, f"unknown function {t!r}"
            arg, rest = self._binary(rest[1:], 0, defined)
            assert rest and rest[0] == ")", "unbalanced call"
            return ("call", t, arg), rest[1:]
        assert t in defined, f"{t!r} used before it is defined"
        return ("var", t), rest

    def evaluate(self, tree, env):
        kind = tree[0]
        if kind == "num":
            return tree[1]
        if kind == "var":
            return env[tree[1]]
        if kind == "neg":
            return -self.evaluate(tree[1], env)
        if kind == "pos":
            return self.evaluate(tree[1], env)
        if kind == "call":
            return self.FUNCTIONS[tree[1]](self.evaluate(tree[2], env))
        a, b = self.evaluate(tree[1], env), self.evaluate(tree[2], env)
        if kind == "+":
            return a + b
        if kind == "-":
            return a - b
        if kind == "*":
            return a * b
        if kind == "/":
            return a / b
        return a**b

    # -- statements
    def parse(self, lines: list[str]) -> None:
        i, depth, module = 0, 0, None
        I = self.IDENT
        while i < len(lines):
            line = lines[i]
            i += 1
            if not line.strip() or line.startswith("#"):
                continue
            if m := re.fullmatch(rf"module ({I})", line):
                assert module is None, "nested module"
                module, depth = m.group(1), 1
            elif re.fullmatch(rf"export {I}(, {I})*", line) or re.fullmatch(rf'const {I} = "([^"\\$]|\\.)*"', line):
                continue  # exports and string constants need no further check
            elif m := re.fullmatch(rf'const ({I}) = (String|Float64)?\[(.*)\]', line):
                items = [x.strip() for x in m.group(3).split(",") if x.strip()]
                if m.group(2) == "Float64":
                    self.consts[m.group(1)] = [float("nan") if x == "NaN" else float(x) for x in items]
                else:
                    assert all(re.fullmatch(r'"([^"\\$]|\\.)*"', x) for x in items), f"bad string list {line!r}"
            elif line == '"""':  # docstring: up to the closing quotes, then a function
                while lines[i] != '"""':
                    assert '"""' not in lines[i], "docstring closed inside a line"
                    i += 1
                i += 1
                assert lines[i].startswith("function "), "a docstring must precede a function"
            elif m := re.fullmatch(rf"function ({I})\((.*)\)", line):
                i = self.function(m.group(1), m.group(2), lines, i)
            elif m := re.fullmatch(rf"end  # module ({I})", line):
                assert m.group(1) == module and depth == 1
                depth = 0
            else:
                raise AssertionError(f"line {i}: not in the emitted grammar: {line!r}")
        assert module and depth == 0, "module not closed"

    def function(self, name: str, signature: str, lines: list[str], i: int) -> int:
        I = self.IDENT
        params = []
        for item in signature.split(", "):
            m = re.fullmatch(rf"({I})::(AbstractVector|AbstractMatrix)(=DEFAULT_PARAMS)?", item)
            assert m, f"bad argument {item!r}"
            params.append(m.group(1))
        defined = set(params)
        program: list[tuple] = []
        while True:
            assert i < len(lines), f"function {name} has no end"
            line = lines[i]
            i += 1
            if line == "end":
                break
            assert line.startswith("    "), f"bad indentation: {line!r}"
            body = line[4:]
            if m := re.fullmatch(rf'size\(({I})\) == \((\d+),( \d+)?\) \|\| throw\(DimensionMismatch\("[^"]*"\)\)', body):
                shape = tuple(int(g) for g in m.groups()[1:] if g)
                program.append(("size", m.group(1), shape))
            elif m := re.fullmatch(rf"({I}) = ({I})\[(\d+)(?:, (\d+))?\]", body):
                assert m.group(2) in params
                program.append(("load", m.group(1), m.group(2), tuple(int(g) - 1 for g in m.groups()[2:] if g)))
                defined.add(m.group(1))
            elif m := re.fullmatch(rf"out = zeros\(promote_type\(eltype\({I}\)(, eltype\({I}\))*\), (\d+(, \d+)*)\)", body):
                program.append(("zeros", tuple(int(d) for d in m.group(2).split(", "))))
                defined.add("out")
            elif m := re.fullmatch(r"out\[(\d+(?:, \d+)*)\] = (.+)", body):
                program.append(("store", tuple(int(d) - 1 for d in m.group(1).split(", ")),
                                self.expression(m.group(2), defined)))
            elif m := re.fullmatch(rf"({I}) = (.+)", body):
                program.append(("assign", m.group(1), self.expression(m.group(2), defined)))
                defined.add(m.group(1))
            elif body == "return out":
                program.append(("return",))
            else:
                raise AssertionError(f"{name}: not in the emitted grammar: {line!r}")
        assert program[-1] == ("return",), f"{name} must end with return out"
        self.functions[name] = (params, program)
        return i

    def call(self, name: str, *args):
        params, program = self.functions[name]
        env = dict(zip(params, args))
        if "p" not in env:
            env["p"] = np.array(self.consts["DEFAULT_PARAMS"])
        out = None
        for step in program:
            if step[0] == "size":
                assert np.shape(env[step[1]]) == step[2]
            elif step[0] == "load":
                env[step[1]] = float(np.asarray(env[step[2]])[step[3]])
            elif step[0] == "zeros":
                out = np.zeros(step[1])
            elif step[0] == "store":
                out[step[1]] = self.evaluate(step[2], env)
            elif step[0] == "assign":
                env[step[1]] = self.evaluate(step[2], env)
        return out


def test_julia_parses_and_evaluates(case):
    (path,) = case.files["julia"]
    jl = JuliaChecker(path.read_text())
    assert set(jl.functions) == set(case.names)
    np.testing.assert_array_equal(jl.consts["DEFAULT_PARAMS"], case.params)
    for name in case.names:
        for s, (state, ref) in enumerate(zip(case.states, case.ref[name])):
            close(jl.call(name, *(state[a] for a in case.args(name))), ref, f"{name} state {s}")


def test_julia_checker_rejects_malformed_code():
    good = 'module m\nfunction f(q::AbstractVector, p::AbstractVector=DEFAULT_PARAMS)\n    x0 = q[1]\n' \
           '    out = zeros(promote_type(eltype(q), eltype(p)), 1)\n    out[1] = -x0^2 + 2.0 .* x0\n    return out\nend\n' \
           'end  # module m\n'
    jl = JuliaChecker(good)
    assert jl.call("f", np.array([3.0]), np.zeros(0))[0] == -9.0 + 6.0
    for bad in (
        good.replace("x0^2", "x0^^2"),                          # not an expression
        good.replace("    return out\nend\n", "    return out\n"),  # function without end
        good.replace("out[1] = -x0", "out[1] = -y0"),           # undefined name
        good.replace("-x0^2", "-(x0^2"),                        # unbalanced parenthesis
        good.replace("end  # module m\n", ""),                   # module without end
        good.replace("2.0 .* x0", "foo(x0)"),                   # not a Base math function
        good.replace("    x0 = q[1]", "x0 = q[1]"),             # not indented: not a statement
    ):
        with pytest.raises(AssertionError):
            JuliaChecker(bad)


# ------------------------------------------------------------------------------------------ LaTeX
def test_latex_document_is_well_formed(case, tmp_path):
    (path,) = case.files["latex"]
    text = path.read_text()
    body = "\n".join(line for line in text.splitlines() if not line.startswith("%"))
    assert body.lstrip().startswith(r"\documentclass") and body.rstrip().endswith(r"\end{document}")
    stack = []
    for m in re.finditer(r"\\(begin|end)\{([^}]*)\}", body):
        if m.group(1) == "begin":
            stack.append(m.group(2))
        else:
            assert stack and stack.pop() == m.group(2), f"unbalanced \\end{{{m.group(2)}}}"
    assert not stack
    unescaped = re.sub(r"\\[{}]", "", body)
    assert unescaped.count("{") == unescaped.count("}")
    for line in body.splitlines():
        assert re.sub(r"\\\$", "", line).count("$") % 2 == 0, f"unbalanced math: {line[:60]!r}"
    aligns = re.findall(r"\\begin\{align\*\}\n(.*?)\n\\end\{align\*\}", body, re.S)
    assert len(aligns) == len(case.names)
    for name, block in zip(case.names, aligns):  # one row per assignment and per output entry
        rows = block.split(" \\\\\n")
        assert len(rows) == len(case.eqs.program([name])) + len(case.eqs.quantities[name].outputs)
        assert all(row.count("&=") == 1 for row in rows)
    for p in case.eqs.parameters:
        assert p.replace("_", r"\_") in body
    pdflatex = shutil.which("pdflatex")
    assert pdflatex, "pdflatex is required: apt-get install -y --no-install-recommends texlive-latex-base"
    proc = subprocess.run([pdflatex, "-interaction=nonstopmode", "-halt-on-error", str(path)], cwd=tmp_path,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert (tmp_path / f"{case.stem}.pdf").stat().st_size > 0


# ------------------------------------------------------------------------------------------ headers and API
def test_every_file_has_the_header(case):
    for target, paths in case.files.items():
        if target == "jax":
            continue
        for path in paths:
            text = path.read_text()
            if path.name.startswith("build_"):
                assert f"{case.stem}_cython.pyx" in text
                continue
            assert repr(case.robot.name) in text or case.robot.name in text, path
            for name in case.names:
                assert name in text, (path, name)
            for k, (p, v) in enumerate(zip(case.eqs.parameters, case.params)):
                base = 1 if target in ("julia", "matlab", "latex") else 0
                if target != "latex":
                    assert re.search(rf"\b{k + base}\s+{re.escape(p)} = {re.escape(repr(float(v)))}", text), (path, p)


def test_generate_refuses_to_overwrite(tmp_path):
    robot = load("arm_2r")
    eqs = jaxskid.derive(robot, ["gravity_torques"])
    paths = codegen.generate(eqs, "c", tmp_path)
    before = paths[0].read_text()
    paths[0].write_text("edited")
    with pytest.raises(FileExistsError, match="already exist"):
        codegen.generate(eqs, "c", tmp_path)
    assert paths[0].read_text() == "edited"
    codegen.generate(eqs, "c", tmp_path, force=True)
    assert paths[0].read_text() == before
    with pytest.raises(jaxskid.RequestError, match="unknown target"):
        codegen.generate(eqs, "fortran", tmp_path)
    with pytest.raises(jaxskid.RequestError, match="not derived"):
        codegen.emit(eqs, "c", ["mass_matrix"])


def test_one_layout_serves_every_target():
    """Emitting from one Layout (renamed once) gives the files that emitting from the equations gives."""
    eqs = jaxskid.derive(load("arm_2r"), ["gravity_torques", "external_torques"])
    layout = codegen.Layout(eqs, tuple(eqs.quantities))
    for target in codegen.TARGETS:
        assert codegen.emit(layout, target) == codegen.emit(eqs, target), target
    with pytest.raises(jaxskid.RequestError, match="in the Layout"):
        codegen.emit(layout, "c", ["gravity_torques"])


def test_wide_outputs_stay_within_pythons_nesting_limit():
    """A result with hundreds of entries along an axis (the regressor of a 43-DOF humanoid: 43 x 430) is
    assembled in pieces: Python's parser refuses 200 nested parentheses."""
    import jax
    import sympy as sp

    from jaxskid.codegen._jax import JaxPrinter, _assemble

    x = sp.Symbol("x", real=True)
    shape = (2, 450)
    outputs = tuple(x * (k + 1) if k % 3 else sp.Integer(0) for k in range(900))
    body = _assemble(shape, outputs, JaxPrinter(), "jnp.float64")
    ns = {"jnp": jnp, "jax": jax}
    exec("def f(x):\n" + "\n".join("    " + line for line in body), ns)  # noqa: S102
    expect = np.array([2.0 * (k + 1) if k % 3 else 0.0 for k in range(900)]).reshape(shape)
    np.testing.assert_array_equal(np.asarray(ns["f"](jnp.float64(2.0))), expect)
