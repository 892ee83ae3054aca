"""The map of the package, made from its code: docs/architecture.md's folder table,
its data-flow figure (figures/architecture.png) and its table of module sizes.

The folder table is each folder's own docstring (its first paragraph); the
figure's arrows are :data:`FLOW`, each checked against the imports before it is
drawn (an arrow A → B says that B uses what A makes, so B imports A); the sizes
are ``wc -l``. ``tests/test_architecture.py`` checks the same arrows, the size
limits and that no import circle or private cross-module import comes back.

    python studies/architecture.py
"""
from __future__ import annotations

import ast
import re
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "symcushion"
DOC = ROOT / "docs" / "architecture.md"
FIGURE = ROOT / "figures" / "architecture.png"

#: The package's parts from the ground up: (part, row of the figure, column).
#: A part is a folder or a top-level module of ``symcushion/``.
PARTS = {
    "validation": (0, 0.6), "legs": (0, 1.8), "contact": (0, 3.0),
    "layout": (1, 0.1), "model": (1, 1.2),
    "scheme": (2, 1.8),
    "run": (3, 0.6), "compiled": (3, 2.6),
    "viz": (4, 0), "peers": (4, 0.75), "envelope": (4, 2.6), "studies": (4, 3.6),
    "design": (5, 2.6), "cli_scenes": (5, 0.9),
    "reproduce": (6, 0.3), "check_files": (6, 1.3), "cli": (6, 2.4), "cli_parser": (6, 3.5),
}
#: The data flow: (from, to, what flows). Each is an import of ``to`` from ``from``.
FLOW = (
    ("legs", "model", "legs"),
    ("model", "scheme", "Model + Scheme"),
    ("legs", "scheme", "P(r), D_p (2.1)"),
    ("contact", "scheme", "contact step (§1)"),
    ("layout", "scheme", "x, p, y fields"),
    ("scheme", "run", "touchdown_step(x, p, dt)"),
    ("scheme", "compiled", "named Functions"),
    ("run", "viz", "Trajectory"),
    ("compiled", "envelope", "compiled rollouts"),
    ("scheme", "envelope", "touchdown_step"),
    ("envelope", "design", "scenarios, P(stable)"),
    ("compiled", "design", "compiled NLP"),
    ("run", "reproduce", "runs of Figs. 3–4"),
    ("design", "cli", "designs"),
    ("run", "cli", "runs"),
)


def part_of(module: str) -> str | None:
    """The part (folder or top-level module) of a dotted ``symcushion.…`` name."""
    pieces = module.split(".")
    return pieces[1] if pieces[0] == "symcushion" and len(pieces) > 1 else None


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def imports() -> dict:
    """{module: set of the symcushion modules it imports} over every module."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        found = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                found |= {node.module} | {f"{node.module}.{a.name}" for a in node.names}
            elif isinstance(node, ast.Import):
                found |= {a.name for a in node.names}
        out[module_name(path)] = {m for m in found if m.startswith("symcushion")}
    return out


def part_imports(graph: dict) -> dict:
    """{part: parts it imports}, the folders' edges."""
    out = defaultdict(set)
    for module, targets in graph.items():
        for target in targets:
            a, b = part_of(module), part_of(target)
            if a and b and a != b:
                out[a].add(b)
    return out


def check_flow(graph: dict) -> list:
    """The arrows of :data:`FLOW` that no import backs."""
    edges = part_imports(graph)
    return [f"{a} -> {b}" for a, b, _ in FLOW if a not in edges.get(b, set())]


def folder_table() -> str:
    """The folder map: each folder's first docstring paragraph and its modules."""
    rows = ["| part | what it owns | modules |", "|---|---|---|"]
    for part in sorted(PARTS, key=lambda p: (PARTS[p][0], PARTS[p][1])):
        path = PACKAGE / part
        init = path / "__init__.py" if path.is_dir() else path.with_suffix(".py")
        doc = ast.get_docstring(ast.parse(init.read_text())).split("\n\n")[0]
        doc = re.sub(r":\w+:`~?\.?([^`]+)`", r"`\1`", " ".join(doc.split()))
        doc = doc.replace("``", "`").replace("|", "\\|")
        if path.is_dir():
            names = sorted(p.relative_to(path).with_suffix("").as_posix()
                           for p in path.rglob("*.py") if p.name != "__init__.py"
                           and "__pycache__" not in p.parts)
            cell = ", ".join(f"`{n}`" for n in names)
            label = f"`{part}/`"
        else:
            cell, label = "—", f"`{part}.py`"
        rows.append(f"| {label} | {doc} | {cell} |")
    return "\n".join(rows) + "\n"


def api_list() -> str:
    """The public API: the names ``symcushion/__init__.py`` exports."""
    import symcushion

    names = ", ".join(f"`{n}`" for n in symcushion.__all__)
    return ("What `import symcushion` gives (its `__all__`; everything else is imported "
            f"from its module):\n\n{names}.\n")


def function_lengths() -> list:
    """(lines, module, function) of every function of the package."""
    out = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                out.append((node.end_lineno - node.lineno + 1,
                            str(path.relative_to(ROOT)), node.name))
    return sorted(out, reverse=True)


def size_table() -> str:
    """Lines per module, by folder."""
    by_folder = defaultdict(list)
    total = 0
    for path in sorted(PACKAGE.rglob("*.py")):
        lines = len(path.read_text().splitlines())
        total += lines
        by_folder[path.parent.relative_to(ROOT).as_posix()].append(f"`{path.stem}` {lines}")
    longest = function_lengths()[0]
    sizes = sorted(((len(p.read_text().splitlines()), p.relative_to(ROOT).as_posix())
                    for p in PACKAGE.rglob("*.py")), reverse=True)
    head = (f"Lines per module of the package ({sum(map(len, by_folder.values()))} modules, "
            f"{total} lines; made by `python studies/architecture.py`). The guide: no "
            f"module over 500 lines, no function over 120. The largest module is "
            f"`{sizes[0][1]}` ({sizes[0][0]}); the longest function `{longest[2]}` of "
            f"`{longest[1]}` ({longest[0]} lines).\n\n")
    rows = ["| folder | modules (lines) |", "|---|---|"]
    rows += [f"| `{folder}/` | {', '.join(names)} |" for folder, names in sorted(by_folder.items())]
    return head + "\n".join(rows) + "\n"


def draw(path: Path):
    """The data-flow figure: the parts as boxes by row, :data:`FLOW` as arrows."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(11, 8))
    xy = {p: (col * 2.6, row * 1.25) for p, (row, col) in PARTS.items()}
    for a, b, label in FLOW:
        (x0, y0), (x1, y1) = xy[a], xy[b]
        ax.annotate("", xy=(x1, y1 - 0.22), xytext=(x0, y0 + 0.22),
                    arrowprops=dict(arrowstyle="-|>", color="0.45", lw=1.1,
                                    shrinkA=2, shrinkB=2))
        ax.text((x0 + x1) / 2, (y0 + y1) / 2, label, fontsize=7.5, color="0.25",
                ha="center", va="center", bbox=dict(fc="white", ec="none", pad=0.5))
    for part, (x, y) in xy.items():
        name = f"{part}/" if (PACKAGE / part).is_dir() else f"{part}.py"
        ax.text(x, y, name, ha="center", va="center", fontsize=10, family="monospace",
                bbox=dict(boxstyle="round,pad=0.35", fc="#dce8f4", ec="#2f5f8f"))
    ax.set_xlim(-1.3, 3.5 * 2.6 + 1.3)
    ax.set_ylim(-0.6, 6 * 1.25 + 0.6)
    ax.axis("off")
    ax.set_title("symcushion: what flows between its parts (A → B: B imports A)", fontsize=11)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    tmp.replace(path)


def main() -> int:
    sys.path.insert(0, str(ROOT))
    from symcushion.run.report import write_section

    graph = imports()
    missing = check_flow(graph)
    if missing:
        print("arrows no import backs:", ", ".join(missing), file=sys.stderr)
        return 1
    draw(FIGURE)
    write_section(DOC, "Folders", folder_table(), title="# Architecture")
    write_section(DOC, "Public API", api_list(), title="# Architecture")
    write_section(DOC, "Module sizes", size_table(), title="# Architecture")
    print(f"wrote {FIGURE} and the folder and size tables of {DOC}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
