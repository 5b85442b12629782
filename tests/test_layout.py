"""The harness's layout (issue 46): one name per module across the whole tree, no import circle among
the harness's modules, every harness import naming a module that exists, and imports that run one way,
harness -> datasets -> spq. The oracle is the source itself, parsed with ast (nothing is imported)."""

from __future__ import annotations

import ast
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
HARNESS = ROOT / "harness"


def module_name(path: Path) -> str:
    """harness/suites/fuzz/judge.py -> harness.suites.fuzz.judge; a package's __init__.py -> the package."""
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules_of(folder: Path) -> dict[str, Path]:
    return {module_name(p): p for p in sorted(folder.rglob("*.py"))}


HARNESS_MODULES = modules_of(HARNESS)


def imports(path: Path, module_level_only: bool) -> set[str]:
    """The modules that path imports, absolute and dotted (``from a import b`` gives a.b when a.b is a
    harness module, else a). module_level_only: what runs when the module is imported (function
    bodies and ``if TYPE_CHECKING:`` blocks left out; class bodies kept)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    this = module_name(path)
    package = this if path.name == "__init__.py" else this.rpartition(".")[0]
    found: set[str] = set()

    def visit(node):
        for child in ast.iter_child_nodes(node):
            if module_level_only and isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                continue
            if module_level_only and isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                continue
            if isinstance(child, ast.Import):
                found.update(a.name for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:  # relative: resolved against this module's package
                    anchor = package.split(".")
                    anchor = anchor[: len(anchor) - (child.level - 1)]
                    base = ".".join(anchor + ([base] if base else []))
                for a in child.names:
                    sub = f"{base}.{a.name}"
                    found.add(sub if sub in HARNESS_MODULES else base)
            visit(child)

    visit(tree)
    return found


def test_no_two_harness_modules_share_a_name():
    # a module is a file (its basename) or a package (its folder's name): harness.suites.check and a
    # harness/check.py would both be "check"
    names = [p.stem for p in HARNESS.rglob("*.py") if p.name != "__init__.py"]
    names += [p.parent.name for p in HARNESS.rglob("__init__.py") if p.parent != HARNESS]
    repeated = sorted(n for n, c in Counter(names).items() if c > 1)
    assert repeated == [], f"module names used twice under harness/: {repeated}"


def test_every_harness_import_names_a_module_that_exists():
    # lazy imports too (inside functions), in the harness and in the tests: a move that left an import
    # behind shows here, not only when that function first runs
    stale = []
    for path in [*HARNESS.rglob("*.py"), *(ROOT / "tests").rglob("*.py")]:
        for name in imports(path, module_level_only=False):
            if name.split(".")[0] == "harness" and name not in HARNESS_MODULES:
                stale.append(f"{path.relative_to(ROOT)}: {name}")
    assert stale == []


def module_graph() -> dict[str, set[str]]:
    """Module -> the harness modules its import runs: those it names and their packages (a package's
    __init__ runs before its module), leaving out the packages this module itself sits in (they are
    already being imported when it runs)."""
    graph = {}
    for name, path in HARNESS_MODULES.items():
        own = {".".join(name.split(".")[:k]) for k in range(1, name.count(".") + 1)}
        edges = set()
        for target in imports(path, module_level_only=True):
            if target.split(".")[0] != "harness":
                continue
            parts = target.split(".")
            edges |= {".".join(parts[:k]) for k in range(2, len(parts) + 1)} - own
            edges.add(target)
        graph[name] = (edges & set(HARNESS_MODULES)) - {name}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str]:
    """One import circle of the graph (a list of modules, the first repeated last), or []."""
    WHITE, GREY, BLACK = 0, 1, 2
    colour = dict.fromkeys(graph, WHITE)
    stack: list[str] = []

    def dfs(node) -> list[str]:
        colour[node] = GREY
        stack.append(node)
        for nxt in sorted(graph[node]):
            if colour[nxt] == GREY:
                return stack[stack.index(nxt):] + [nxt]
            if colour[nxt] == WHITE and (cycle := dfs(nxt)):
                return cycle
        stack.pop()
        colour[node] = BLACK
        return []

    for node in sorted(graph):
        if colour[node] == WHITE and (cycle := dfs(node)):
            return cycle
    return []


def test_find_cycle_finds_a_circle_and_only_a_circle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) == []


def test_no_import_circle_among_harness_modules():
    assert find_cycle(module_graph()) == []


def test_imports_run_one_way_harness_datasets_spq():
    # spq never imports harness or datasets; datasets never imports harness (lazy imports included)
    wrong = []
    for folder, banned in (("spq", {"harness", "datasets"}), ("datasets", {"harness"})):
        for path in (ROOT / folder).rglob("*.py"):
            for name in imports(path, module_level_only=False):
                if name.split(".")[0] in banned:
                    wrong.append(f"{path.relative_to(ROOT)}: {name}")
    assert wrong == []
