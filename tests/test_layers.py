"""The package's layering (docs/design.md, "Modules"): what each layer may import (the table's "may import"
column), no module imports a layer above its own, no import cycle; and the scripts: none imports another,
none assigns to an attribute of a parsph module (a patch where a seam belongs).

Read from the sources with ``ast`` (every import statement, inside functions too), not from the code
under test.
"""
import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PKG = ROOT / "parsph"

# docs/design.md's Modules table, bottom first: each layer and its "may import" column word for word
# (test_the_table_is_design_mds holds the two together). The column names parsph's parts in WORDS below,
# "(never ...)" notes what the list already leaves out, "X (a, b)" allows only the parts a and b of X,
# and after a ";" come the third-party packages of EXTERNAL that the layer may import.
TABLE = [
    ("parsph/errors.py", "nothing of parsph"),
    ("parsph/numba_cache.py", "nothing of parsph"),
    ("parsph/compile_settings.py", "nothing of parsph"),
    ("parsph/blas_threads.py", "nothing of parsph"),
    ("parsph/physics/", "errors"),
    ("parsph/sph/", "physics"),
    ("parsph/gas/", "errors, physics"),
    ("parsph/parallel/", "errors, sph's particles and cell grid (never the equations); mpi4py"),
    ("parsph/output/", "nothing of parsph but its version; h5py, mpi4py"),
    ("parsph/setup/", "errors, physics, sph (particle kinds, integrator names, the cell grid)"),
    ("parsph/simulation/", "all of the above"),
    ("parsph/studies/", "all of the above"),
    ("parsph/cli/", "everything"),
]
WORDS = {"errors": "parsph.errors", "physics": "parsph.physics", "sph": "parsph.sph",
         "sph's particles": "parsph.sph.particles", "particle kinds": "parsph.sph.particles",
         "cell grid": "parsph.sph.cells", "the cell grid": "parsph.sph.cells",
         "integrator names": "parsph.sph.integrators", "its version": "parsph"}
EXTERNAL = ("mpi4py", "h5py")   # checked: MPI and parallel HDF5 only where the table says (numpy, numba: anywhere)
# outside the table: the package's __init__ (the version) applies the BLAS and numba settings on import;
# python -m parsph
OUTSIDE = {"parsph": {"parsph.numba_cache", "parsph.compile_settings", "parsph.blas_threads"}, "parsph.__main__": {"parsph.cli"}}
# imports the column does not allow today, each to be settled in design.md's table or in the code (a listed
# import that is gone fails test_known_exceptions_are_current, so this list cannot go stale)
KNOWN = {}


def layer_name(path):
    """parsph/physics/ -> parsph.physics; parsph/errors.py -> parsph.errors."""
    return path.rstrip("/").removesuffix(".py").replace("/", ".")


LAYERS = [layer_name(p) for p, _ in TABLE]


def rules():
    """{layer: (parsph modules or packages it may import, the EXTERNAL packages it may import)}."""
    out = {}
    for path, text in TABLE:
        name = layer_name(path)
        parts, _, ext = text.partition(";")
        parts = re.sub(r"\s*\(never [^)]*\)", "", parts.strip())
        if parts == "everything":
            allowed, externals = set(LAYERS) | {"parsph"}, set(EXTERNAL)
        elif parts == "all of the above":
            allowed = set(LAYERS[:LAYERS.index(name)]) | {"parsph"}
            externals = set().union(*(out[lay][1] for lay in allowed if lay in out))
        else:
            # "sph (particle kinds, ...)": the parts named in the brackets stand for the word before them
            parts = re.sub(r"\w+ \(([^)]*)\)", r"\1", parts)
            if parts.startswith("nothing of parsph"):
                parts = parts.removeprefix("nothing of parsph").removeprefix(" but")
            words = [w.strip() for w in re.split(r",| and ", parts) if w.strip()]
            allowed, externals = {WORDS[w] for w in words}, set()
        externals |= {e.strip() for e in ext.split(",") if e.strip()}
        assert externals <= set(EXTERNAL), (name, externals)
        out[name] = (allowed, externals)
    return out


def module_name(path):
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_module(dotted):
    p = ROOT / dotted.replace(".", "/")
    return p.with_suffix(".py").exists() or (p / "__init__.py").exists()


def imports(path):
    """(the parsph modules or packages that ``path`` imports, the top-level names of the others).

    ``from parsph.sph import particles`` imports the module parsph.sph.particles (not parsph.sph's own
    names); ``from parsph.setup.config import build`` imports parsph.setup.config."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    ours, others = set(), set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            for a in node.names:
                (ours if a.name.split(".")[0] == "parsph" else others).add(
                    a.name if a.name.split(".")[0] == "parsph" else a.name.split(".")[0])
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[:len(package.split(".")) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.split(".")[0] != "parsph":
                others.add(mod.split(".")[0])
                continue
            for a in node.names:
                sub = f"{mod}.{a.name}"
                ours.add(sub if _is_module(sub) else mod)
    return ours, others


def layer(mod):
    """The index in LAYERS of the layer holding ``mod`` (-1: the package's __init__)."""
    if mod == "parsph.__main__":  # python -m parsph: the command line
        return LAYERS.index("parsph.cli")
    return max((i for i, top in enumerate(LAYERS) if mod == top or mod.startswith(top + ".")), default=-1)


def graph():
    return {module_name(p): imports(p)[0] for p in sorted(PKG.rglob("*.py"))}


def _within(mod, allowed):
    """``mod`` is one of ``allowed`` or inside one of them (the package's __init__, "parsph": itself only)."""
    return any(mod == a or (a != "parsph" and mod.startswith(a + ".")) for a in allowed)


def violations():
    """{(module, import): why} of every import the table does not allow."""
    rule = rules()
    bad = {}
    for p in sorted(PKG.rglob("*.py")):
        m = module_name(p)
        ours, others = imports(p)
        if m in OUTSIDE:
            allowed, externals = OUTSIDE[m], set()
        else:
            own = LAYERS[layer(m)]
            allowed, externals = rule[own][0] | {own}, rule[own][1]
        for i in sorted(ours):
            if not _within(i, allowed):
                bad[(m, i)] = f"{m} imports {i}: its layer may import {sorted(allowed)}"
        for e in sorted(set(EXTERNAL) & others - externals):
            bad[(m, e)] = f"{m} imports {e}, which its layer may not"
    return bad


def test_each_layer_imports_only_what_design_md_allows():
    bad = [why for key, why in violations().items() if key not in KNOWN]
    assert not bad, "\n".join(bad)


def test_known_exceptions_are_current():
    gone = sorted(set(KNOWN) - set(violations()))
    assert not gone, f"no longer imported or now allowed, remove from KNOWN: {gone}"


def test_the_table_is_design_mds():
    """TABLE is docs/design.md's Modules table (its first two columns), row for row."""
    rows = []
    for line in (ROOT / "docs" / "design.md").read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("| `parsph/") and len(cells) >= 3:
            rows.append((cells[0].strip("`"), cells[1]))
    assert rows == TABLE


def test_every_module_lies_in_a_layer():
    loose = [m for m in graph() if layer(m) < 0 and m not in OUTSIDE]
    assert not loose, loose


def test_no_module_imports_a_layer_above_its_own():
    bad = [f"{m} ({LAYERS[layer(m)]}) imports {i} ({LAYERS[layer(i)]})"
           for m, deps in graph().items() if m not in OUTSIDE for i in sorted(deps) if layer(i) > layer(m)]
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


def test_rules_read_as_meant():
    """A few rules spelled out, so that a change of the parser shows."""
    r = rules()
    assert r["parsph.output"] == ({"parsph"}, {"h5py", "mpi4py"})
    assert r["parsph.physics"] == ({"parsph.errors"}, set())
    assert r["parsph.parallel"] == ({"parsph.errors", "parsph.sph.particles", "parsph.sph.cells"}, {"mpi4py"})
    assert r["parsph.setup"][0] == {"parsph.errors", "parsph.physics", "parsph.sph.particles", "parsph.sph.integrators",
                                    "parsph.sph.cells"}
    assert not _within("parsph.sph.momentum", r["parsph.parallel"][0])
    assert r["parsph.studies"][1] == {"h5py", "mpi4py"} and "parsph.cli" not in r["parsph.studies"][0]


def test_scripts_import_no_script():
    """A script's code that another needs belongs in the package (parsph.studies), not in a sibling script."""
    names = {p.stem for p in (ROOT / "scripts").glob("*.py")}
    found = []
    for p in sorted((ROOT / "scripts").glob("*.py")):
        for n in ast.walk(ast.parse(p.read_text())):
            mods = [a.name for a in n.names] if isinstance(n, ast.Import) else \
                [n.module or ""] if isinstance(n, ast.ImportFrom) and not n.level else []
            found += [f"{p.name} imports {m}" for m in mods if m.split(".")[0] in names]
    assert not found, found


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
