"""The package's layering (docs/design.md, "Modules"): no module imports a layer above its own, no import
cycle, and no script assigns to an attribute of a parsph module (a patch where a seam belongs).

Read from the sources with ``ast`` (every import statement, inside functions too), not from the code
under test.
"""
import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PKG = ROOT / "parsph"
# bottom first; a module may import its own layer and those before it (parsph/__init__: the version)
LAYERS = ["parsph", "parsph.errors", "parsph.physics", "parsph.sph", "parsph.parallel", "parsph.output",
          "parsph.setup", "parsph.simulation", "parsph.studies", "parsph.cli"]


def module_name(path):
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path):
    """The parsph modules (or packages) that ``path`` imports."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.split(".")[0] == "parsph"}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[:len(package.split(".")) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.split(".")[0] != "parsph":
                continue
            out.add(mod)
            for a in node.names:  # "from parsph.setup import config" imports the module parsph.setup.config
                if (PKG.parent / (mod.replace(".", "/") + "/" + a.name + ".py")).exists() or \
                        (PKG.parent / mod.replace(".", "/") / a.name / "__init__.py").exists():
                    out.add(f"{mod}.{a.name}")
    return out


def layer(mod):
    if mod == "parsph.__main__":  # python -m parsph: the command line
        return LAYERS.index("parsph.cli")
    return max(i for i, top in enumerate(LAYERS) if mod == top or mod.startswith(top + "."))


def graph():
    return {module_name(p): imports(p) for p in sorted(PKG.rglob("*.py"))}


def test_no_module_imports_a_layer_above_its_own():
    bad = [f"{m} ({LAYERS[layer(m)]}) imports {i} ({LAYERS[layer(i)]})"
           for m, deps in graph().items() for i in sorted(deps) if layer(i) > layer(m)]
    assert not bad, "\n".join(bad)


def test_no_import_cycle():
    g = graph()
    g = {m: {d for d in deps if d in g and d != m and not m.startswith(d + ".")} for m, deps in g.items()}
    state, cycles = {}, []

    def visit(m, stack):
        state[m] = "open"
        for d in sorted(g[m]):
            if state.get(d) == "open":
                cycles.append(" -> ".join(stack[stack.index(d):] + [d]))
            elif d not in state:
                visit(d, stack + [d])
        state[m] = "done"
    for m in sorted(g):
        if m not in state:
            visit(m, [m])
    assert not cycles, "\n".join(cycles)


def test_scripts_assign_to_no_parsph_attribute():
    """``solver.Simulation.run = ...`` or ``scene.fn = ...`` in a script: the package needs a seam instead."""
    found = set()
    for p in sorted((ROOT / "scripts").glob("*.py")):
        tree = ast.parse(p.read_text())
        bound = set()
        for n in ast.walk(tree):
            if isinstance(n, ast.ImportFrom) and (n.module or "").startswith("parsph"):
                bound |= {a.asname or a.name for a in n.names}
            elif isinstance(n, ast.Import):
                bound |= {(a.asname or a.name).split(".")[0] for a in n.names if a.name.startswith("parsph")}
        for n in ast.walk(tree):
            targets = n.targets if isinstance(n, ast.Assign) else [n.target] if isinstance(n, ast.AugAssign) else []
            for t in targets:
                r = t
                while isinstance(r, ast.Attribute):
                    r = r.value
                if t is not r and isinstance(r, ast.Name) and r.id in bound:
                    found.add(f"{p.relative_to(ROOT)}:{n.lineno}")
    assert not found, sorted(found)
