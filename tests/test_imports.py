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
# the folder of what it is for (data, dataset, model, training, evaluation, native).
TOP_LEVEL = {"__init__", "_llvm", "setup_llvm", "benchmark", "crosscheck", "demo", "evaluate", "optimize", "scene",
             "config", "methods", "conventions", "machine", "runs"}
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
    # plots import no training (the trade-off study trains its runs, so it may)
    readers = [m for m in graph if m == "glint_mi.data" or m.startswith("glint_mi.data.")]
    assert not {d for m in readers for d in graph[m]
                if d.startswith(("glint_mi.model", "glint_mi.training", "glint_mi.evaluation"))}
    leaves = [m for m in graph if m.startswith("glint_mi.evaluation.") and not m.endswith(".tradeoff")]
    assert not {d for m in leaves for d in graph[m] if d.startswith("glint_mi.training")}
