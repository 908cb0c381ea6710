"""The package's import graph (every import, at module level or inside a function): no cycle between glint_mi's
modules, and the dataset readers (glint_mi.data) never import the room generator (glint_mi.dataset)."""
import ast
from pathlib import Path

PKG = Path(__file__).resolve().parent.parent / "glint_mi"


def import_graph() -> dict[str, set[str]]:
    """module -> the glint_mi modules it imports (``import`` and ``from`` forms, relative ones resolved)."""
    files = {}
    for p in PKG.rglob("*.py"):
        parts = p.relative_to(PKG.parent).with_suffix("").parts
        files[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = p
    graph = {}
    for mod, path in files.items():
        package = mod if path.name == "__init__.py" else mod.rsplit(".", 1)[0]
        deps = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[:len(package.split(".")) - node.level + 1]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                names = [target] + [f"{target}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            deps |= {n for n in names if n in files and n != mod}
        graph[mod] = deps
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
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

    for v in graph:
        if v not in index:
            visit(v)
    return out


def test_no_import_cycle():
    graph = import_graph()
    assert len(graph) > 30 and "glint_mi.training.trainer" in graph["glint_mi.optimize"]
    assert cycles(graph) == []
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]  # the detector finds one


def test_readers_do_not_import_the_generator():
    graph = import_graph()
    wrong = sorted((m, d) for m, deps in graph.items() for d in deps
                   if (m.startswith("glint_mi.data.") or m in ("glint_mi.data", "glint_mi.training.batch"))
                   and d.startswith("glint_mi.dataset"))
    assert wrong == []


# The package's top level: the commands (python -m glint_mi.X) and what every part shares. A library module goes in
# the folder of what it is for (data, dataset, model, training, evaluation, native). _llvm and _interrupt are the
# package's start-up (the LLVM it loads, the Ctrl-C hook), which the start-up files run before the package loads.
TOP_LEVEL = {"__init__", "_llvm", "_interrupt", "setup_llvm", "benchmark", "crosscheck", "demo", "evaluate",
             "optimize", "scene", "config", "methods", "conventions", "machine", "runs",
             "tradeoff"}  # a study that trains and evaluates runs, above training and evaluation
FOLDERS = {"data", "dataset", "model", "training", "evaluation", "native"}


def test_layout_shows_the_architecture():
    top = {p.stem for p in PKG.glob("*.py")}
    folders = {p.name for p in PKG.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert top == TOP_LEVEL, f"new top-level modules {sorted(top - TOP_LEVEL)} belong in one of {sorted(FOLDERS)}"
    assert folders == FOLDERS, sorted(folders ^ FOLDERS)
    for folder in FOLDERS:  # each folder says what it holds
        assert ast.get_docstring(ast.parse((PKG / folder / "__init__.py").read_text())), folder
    graph = import_graph()
    # the folders depend downwards: the readers import no model, training or evaluation; the metrics, analyses and
    # plots import no training (the trade-off study, which trains its runs, is a top-level module)
    readers = [m for m in graph if m == "glint_mi.data" or m.startswith("glint_mi.data.")]
    assert not {d for m in readers for d in graph[m]
                if d.startswith(("glint_mi.model", "glint_mi.training", "glint_mi.evaluation"))}
    leaves = [m for m in graph if m.startswith("glint_mi.evaluation")]
    assert not {d for m in leaves for d in graph[m] if d.startswith("glint_mi.training")}


PLUGINS = PKG.parent / "plugins"


def _imports_of(path: Path) -> set[str]:
    """Every module name a file imports (both forms, at any depth; ``from a import b`` gives a and a.b)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and not node.level:
            out |= {node.module} | {f"{node.module}.{a.name}" for a in node.names}
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
    return out


def package_graph() -> dict[str, set[str]]:
    """The import graph of the packages: glint_mi's folders (data, dataset, model, training, evaluation, native)
    each one node, each top-level module its own node (glint_mi is its __init__), and plugins/ one node."""
    graph = import_graph()
    folders = {p.name for p in PKG.iterdir() if p.is_dir() and (p / "__init__.py").exists()}

    def node(mod: str) -> str:
        parts = mod.split(".")
        if parts[0] == "glint_mi_plugins":
            return "plugins"
        return ".".join(parts[:2]) if len(parts) > 1 and parts[1] in folders else mod

    out: dict[str, set[str]] = {}
    for mod, deps in graph.items():
        out.setdefault(node(mod), set()).update(node(d) for d in deps)
    for p in PKG.rglob("*.py"):  # glint_mi -> plugins
        parts = p.relative_to(PKG.parent).with_suffix("").parts
        mod = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[node(mod)].update("plugins" for n in _imports_of(p) if n.startswith("glint_mi_plugins"))
    for p in PLUGINS.glob("*.py"):  # plugins -> glint_mi
        out.setdefault("plugins", set()).update(node(n) for n in _imports_of(p) if n in graph)
    for k in out:
        out[k].discard(k)
    return out


def test_no_cycle_between_packages():
    """A package's modules may import each other; packages depend one way (issue 64: training <-> evaluate, scene,
    evaluation, dataset and model <-> plugins were cycles)."""
    graph = package_graph()
    assert {"plugins", "glint_mi.training", "glint_mi.model"} <= set(graph) and "plugins" in graph["glint_mi.training"]
    assert cycles(graph) == []


def test_real_captures_do_not_import_the_room_generator():
    """What reads a capture and trains on it (scene.py, data/, model/, training/) imports nothing from dataset/, the
    procedural rooms: cameras, SfM triangulation and the priors' record live in data/."""
    graph = import_graph()
    users = [m for m in graph if m == "glint_mi.scene" or m.startswith(("glint_mi.data", "glint_mi.model",
                                                                       "glint_mi.training"))
             and not m.startswith("glint_mi.dataset")]
    assert len(users) > 15
    assert sorted((m, d) for m in users for d in graph[m] if d.startswith("glint_mi.dataset")) == []


def test_the_trainer_imports_few_project_modules():
    """The trainer runs the loop; assembling a run is the builder's (training/builder.py)."""
    deps = {d for d in import_graph()["glint_mi.training.trainer"] if d != "glint_mi"}
    deps |= {n.rsplit(".", 1)[0] if n.count(".") > 1 else n for n in _imports_of(PKG / "training" / "trainer.py")
             if n.startswith("glint_mi_plugins.")}
    assert len(deps) <= 12, sorted(deps)
