"""navsim's modules import each other without a cycle, counting the imports inside functions
too (so that no import is put in a function to dodge one); no function is longer than
:data:`LONGEST` lines, none outside the numba kernels takes more than :data:`MOST_PARAMETERS`
parameters, and a module over :data:`LONGEST_MODULE` lines says why at its top."""

import ast
import subprocess
import sys
from pathlib import Path

import navsim

PACKAGE = Path(navsim.__file__).resolve().parent
#: the layers of the package in the order of the data flow: a module imports only from its own
#: layer and the layers before it (the longest prefix of a module's name gives its layer)
LAYERS = ("navsim.data", "navsim.version", "navsim.foundations", "navsim.flight", "navsim.sensors",
          "navsim.navigation", "navsim.records", "navsim.experiment", "navsim.scoring", "navsim.replay", "navsim.report", "navsim.api",
          "navsim.plugin", "navsim.cli", "navsim.__main__", "navsim")
#: layers that must not import each other although the order would let them: the scoring reads
#: the records (navsim.records), never the experiment that made them
APART = {"navsim.scoring": ("navsim.experiment",)}
#: the longest a function of the package may be, in lines (its docstring included)
LONGEST = 60
#: the most parameters a function outside the numba kernels takes (``self`` and ``cls`` not
#: counted; a kernel's arrays are its interface to compiled code)
MOST_PARAMETERS = 7
#: a module longer than this says at its top (its docstring) why: "over 600 lines, for one concept"
LONGEST_MODULE = 600


def module_names() -> dict:
    """Module name -> file of every navsim module."""
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def absolute(mod: str, path: Path, node: ast.ImportFrom) -> str:
    """The absolute module a ``from ... import`` in module ``mod`` (file ``path``) names."""
    if not node.level:
        return node.module
    package = mod.split(".") if path.name == "__init__.py" else mod.split(".")[:-1]
    base = package[:len(package) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def lazy_targets(mod: str, node: ast.Call) -> list:
    """The submodules a package's ``lazy_loader.attach(__name__, submodules=[...],
    submod_attrs={...})`` loads on first use: imports like any other."""
    names = []
    for kw in node.keywords:
        if kw.arg == "submodules" and isinstance(kw.value, (ast.List, ast.Tuple)):
            names += [e.value for e in kw.value.elts if isinstance(e, ast.Constant)]
        elif kw.arg == "submod_attrs" and isinstance(kw.value, ast.Dict):
            names += [k.value for k in kw.value.keys if isinstance(k, ast.Constant)]
    return [f"{mod}.{n}" for n in names]


def import_graph() -> dict:
    """Module -> the navsim modules it imports anywhere in its file. ``from package import
    name`` counts as an import of the submodule ``package.name`` when there is one (else of the
    package); a submodule attached by ``lazy_loader.attach`` counts as imported."""
    mods = module_names()
    graph = {m: set() for m in mods}
    for mod, path in mods.items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "attach":
                targets = lazy_targets(mod, node)
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and (node.module or node.level):
                module = absolute(mod, path, node)
                subs = [f"{module}.{a.name}" for a in node.names]
                targets = [s for s in subs if s in mods]
                if len(targets) < len(subs):
                    targets.append(module)
            else:
                continue
            graph[mod].update(t for t in targets if t in mods and t != mod)
    return graph


def cycles(graph: dict) -> list:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_graph_sees_the_imports():
    graph = import_graph()
    assert "navsim.api" in graph["navsim"] and "navsim.navigation.kernels.strapdown" in graph["navsim.navigation.strapdown"]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_cycle_inside_functions_included():
    assert cycles(import_graph()) == []


def layer(module: str) -> int:
    """The index in :data:`LAYERS` of a module's layer."""
    matches = [i for i, p in enumerate(LAYERS) if module == p or module.startswith(p + ".")]
    return max(matches, key=lambda i: len(LAYERS[i]))


def upward(graph: dict) -> list:
    """The imports ``(module, imported)`` that point up the layers."""
    return sorted((m, t) for m, ts in graph.items() for t in ts if layer(t) > layer(m))


def test_imports_point_down_the_data_flow():
    graph = import_graph()
    assert set(module_names()) - {"navsim"} <= {m for m in graph if layer(m) < len(LAYERS) - 1}
    assert upward(graph) == []
    # relative imports are resolved: one from sensors up to experiment is seen
    node = ast.parse("from ..experiment import runner").body[0]
    assert absolute("navsim.sensors.imu", PACKAGE / "sensors" / "imu.py", node) == "navsim.experiment"
    # the check sees an upward import
    assert upward({"navsim.sensors.imu": {"navsim.experiment.runner"}}) == [("navsim.sensors.imu", "navsim.experiment.runner")]


def crossing(graph: dict) -> list:
    """The imports ``(module, imported)`` from a layer into one :data:`APART` keeps it from."""
    return sorted((m, t) for m, ts in graph.items() for t in ts for a, bs in APART.items()
                  if layer(m) == LAYERS.index(a) and any(layer(t) == LAYERS.index(b) for b in bs))


def test_the_scoring_imports_nothing_of_the_experiment():
    assert crossing(import_graph()) == []
    # the check sees one
    assert crossing({"navsim.scoring.scorer": {"navsim.experiment.runner", "navsim.records.history"}}) == [
        ("navsim.scoring.scorer", "navsim.experiment.runner")]


def long_functions(path: Path, limit: int) -> list:
    """``(lines, "file:function")`` of the functions in ``path`` longer than ``limit`` lines."""
    tree = ast.parse(path.read_text())
    return [(n.end_lineno - n.lineno + 1, f"{path.parent.name}/{path.name}:{n.name}") for n in ast.walk(tree)
            if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) and n.end_lineno - n.lineno + 1 > limit]


def test_no_function_is_longer_than_the_limit(tmp_path):
    found = [f for path in sorted(PACKAGE.rglob("*.py")) for f in long_functions(path, LONGEST)]
    assert found == [], sorted(found, reverse=True)
    # the walk sees a long function, nested ones too
    body = "\n".join(f"    x{i} = {i}" for i in range(LONGEST))
    (tmp_path / "m.py").write_text(f"class A:\n    def f(self):\n    {body.replace(chr(10), chr(10) + '    ')}\n")
    assert [n for _, n in long_functions(tmp_path / "m.py", LONGEST)] == [f"{tmp_path.name}/m.py:f"]


def _compiled(node) -> bool:
    """Whether a function is a numba kernel (``@njit``, ``@jit``, ``@njit(...)``)."""
    return any("jit" in ast.unparse(d) for d in node.decorator_list)


def many_parameters(path: Path, limit: int) -> list:
    """``(parameters, "file:function")`` of the functions in ``path`` outside the numba
    kernels that take more than ``limit`` parameters (``self``/``cls`` not counted)."""
    out = []
    for n in ast.walk(ast.parse(path.read_text())):
        if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) and not _compiled(n):
            a = n.args
            names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs] + [x.arg for x in (a.vararg, a.kwarg) if x]
            count = len(names) - (names[:1] in (["self"], ["cls"]))
            if count > limit:
                out.append((count, f"{path.parent.name}/{path.name}:{n.name}"))
    return out


def test_no_function_takes_more_than_seven_parameters(tmp_path):
    found = [f for path in sorted(PACKAGE.rglob("*.py")) for f in many_parameters(path, MOST_PARAMETERS)]
    assert found == [], sorted(found, reverse=True)
    # the walk counts keyword-only and star parameters, and leaves the kernels and self out
    (tmp_path / "m.py").write_text("class A:\n    def f(self, a, b, *c, d, e, f, g, **h): pass\n"
                                   "    def g(self, a, b, c, d, e, f, g): pass\n"
                                   "@njit(cache=True)\ndef k(a, b, c, d, e, f, g, h): pass\n")
    assert many_parameters(tmp_path / "m.py", MOST_PARAMETERS) == [(8, f"{tmp_path.name}/m.py:f")]


def test_a_module_over_600_lines_says_why_at_its_top():
    """Its docstring says "over 600 lines" and for what (one concept, a table, ...)."""
    long = {str(p.relative_to(PACKAGE)): ast.get_docstring(ast.parse(p.read_text())) or ""
            for p in sorted(PACKAGE.rglob("*.py")) if len(p.read_text().splitlines()) > LONGEST_MODULE}
    assert {k for k, doc in long.items() if "over 600 lines" not in doc} == set(), long.keys()


def test_a_monte_carlo_worker_loads_neither_the_report_nor_the_scoring_and_the_api_loads_on_use():
    """``import navsim`` attaches the API lazily (lazy_loader): a fresh interpreter that imports
    the worker's module (the chunk work of navsim.experiment.runner) holds no matplotlib,
    scipy.stats, optuna, navsim.api, navsim.scoring or navsim.report; the package's names then
    resolve on first use, every one of ``__all__``."""
    code = ("import sys, navsim.experiment.runner\n"
            "heavy = ['matplotlib', 'scipy.stats', 'optuna', 'navsim.api', 'navsim.scoring', 'navsim.report']\n"
            "print([m for m in heavy if m in sys.modules])\n"
            "import navsim\n"
            "print(all(getattr(navsim, n) is not None for n in navsim.__all__), 'navsim.api' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split("\n")
    assert out[0] == "[]" and out[1] == "True True", out


def test_the_kernel_cache_is_renamed_by_a_change_its_kernels_depend_on(tmp_path):
    """numba keys a cached kernel on its own file: a kernel freezing another module's constants
    (the fleet's COL_* of flight.properties) would load stale after that module changed. The
    cache folder's digest covers the kernels' modules and what they import, nothing else."""
    import shutil
    from pathlib import Path

    from navsim.foundations.compiled import CACHE_FOLDER, kernel_digest
    package = tmp_path / "navsim"
    shutil.copytree(Path(__file__).resolve().parents[2] / "navsim", package,
                    ignore=shutil.ignore_patterns("__pycache__"))
    before = kernel_digest(package)
    assert CACHE_FOLDER is None or CACHE_FOLDER.name == f"kernels-{kernel_digest()}"
    report = package / "report" / "pages.py"
    report.write_text(report.read_text() + "\n# an edit outside the kernels' sources\n")
    assert kernel_digest(package) == before
    props = package / "flight" / "properties.py"             # no kernel in it; fleet.py imports it
    assert b"njit" not in props.read_bytes()
    props.write_text(props.read_text() + "\n# an edit the fleet's kernels depend on\n")
    assert kernel_digest(package) != before
