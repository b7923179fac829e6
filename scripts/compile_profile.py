"""Where the set-up's compile goes: the cases of ``python -m parsph.cli.warm`` (``--suite``: also the test
suite's), run one after the other in this one process on an empty numba cache (a fresh NUMBA_CACHE_DIR, removed
at the end), with numba's ``numba:compile`` events timed in CPU seconds (time.process_time: a shared machine's
other jobs do not count).

    .venv/bin/python scripts/compile_profile.py [--suite] [--top 25] [--only SUBSTRING] [--list]

Prints the CPU seconds of each case (what it added to the cache), of each function (self time: less the
functions compiled inside its compile; its versions, and the switches that differ between them), of each switch
value, of the versions specialised on a literal argument (a constant at the call site: one version per value),
and of the ``parallel=True`` functions, those compiled by one-thread cases apart. A switch is a compile-time
switch (``pass_data.switch``: () or (1,)) among a version's argument types: a field of a named tuple of them
(pass_data.Switches, block.Modes, whatever their fields) or an argument of its own (``arg.NAME``).
"""
import argparse
import os
import shutil
import sys
import tempfile
import time
from collections import defaultdict

CACHE = tempfile.mkdtemp(prefix="parsph-profile-cache-")
os.environ["NUMBA_CACHE_DIR"] = CACHE  # before numba is imported: every case compiles from nothing
os.environ.setdefault("NUMBA_NUM_THREADS", "2")


def _is_switch(t):
    from numba.core import types
    return isinstance(t, types.BaseTuple) and not isinstance(t, types.BaseNamedTuple) and len(t) <= 1 and \
        all(isinstance(e, types.Integer) for e in t)


def switch_values(argtypes, params=()):
    """{(group, name): on} of the compile-time switches among a version's argument types: the fields of a
    named tuple of switches (group: its class) and switch arguments of their own (group: "arg", name: the
    parameter's name in ``params``)."""
    from numba.core import types
    out = {}
    for k, t in enumerate(argtypes):
        cls = getattr(t, "instance_class", None)
        fields = getattr(cls, "_fields", None)
        if isinstance(t, types.BaseNamedTuple) and fields:
            elems = list(t.types) if hasattr(t, "types") else [t.dtype] * t.count
            if all(_is_switch(e) for e in elems):
                out.update({(cls.__name__, f): len(e) == 1 for f, e in zip(fields, elems)})
        elif _is_switch(t) and k < len(params):
            out[("arg", params[k])] = len(t) == 1
    return out


class Recorder:
    """The numba:compile events as a tree: each version's CPU seconds in all and less its children's."""

    def __init__(self):
        self.stack, self.done, self.case = [], [], None

    def on_start(self, ev):
        self.stack.append([ev.data["dispatcher"], tuple(ev.data["args"]), time.process_time(), 0.0])

    def on_end(self, ev):
        disp, args, t0, children = self.stack.pop()
        total = time.process_time() - t0
        if self.stack:
            self.stack[-1][3] += total
        py = disp.py_func
        params = py.__code__.co_varnames[:py.__code__.co_argcount] if py.__module__.startswith("parsph") else ()
        self.done.append(dict(name=f"{py.__module__.removeprefix('parsph.')}.{py.__qualname__}", args=args,
                              switches=switch_values(args, params),
                              total=total, self=total - children, parallel=bool(disp.targetoptions.get("parallel")),
                              outer=not self.stack, case=self.case))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run-dir", help="run files (default: the repository's run/)")
    ap.add_argument("--top", type=int, default=25, help="functions listed (default 25)")
    ap.add_argument("--suite", action="store_true", help="warm --suite's cases (main.sh's and the test suite's)")
    ap.add_argument("--only", help="run only the cases whose description contains this")
    ap.add_argument("--list", action="store_true", help="also list every version compiled: case, function, CPU s")
    a = ap.parse_args(argv)
    from numba.core import event
    from parsph.cli import warm
    from parsph.cli.command import main as parsph
    rec = Recorder()
    listener = type("L", (event.Listener,), {"on_start": lambda s, e: rec.on_start(e),
                                              "on_end": lambda s, e: rec.on_end(e)})()
    event.register("numba:compile", listener)
    cases = warm.variants(a.run_dir or warm.RUN_DIR, a.suite)
    per_case = []
    c0 = time.process_time()
    with tempfile.TemporaryDirectory(prefix="parsph-profile-out-") as out:
        for k, case in enumerate(cases):
            desc = warm.describe(case)
            if a.only and a.only not in desc:
                continue
            rec.case = desc
            t0, n0 = time.process_time(), len(rec.done)
            code, _ = warm.run_case(parsph, case, os.path.join(out, str(k)))
            per_case.append((desc, time.process_time() - t0,
                             sum(d["total"] for d in rec.done[n0:] if d["outer"]), len(rec.done) - n0, code))
    total = time.process_time() - c0
    compiling = sum(d["self"] for d in rec.done)
    print(f"# {len(per_case)} cases, {total:.1f} CPU s in all, {compiling:.1f} of it compiling "
          f"({len(rec.done)} versions of {len({d['name'] for d in rec.done})} functions)\n")
    print("| case | CPU s | compiling | versions |\n| --- | ---: | ---: | ---: |")
    for desc, cpu, comp, n, code in per_case:
        print(f"| {desc}{'' if code == 0 else f' (exit {code})'} | {cpu:.1f} | {comp:.1f} | {n} |")
    fn = defaultdict(list)
    for d in rec.done:
        fn[d["name"]].append(d)
    print("\n| function | self CPU s | versions | parallel=True | switches that differ between its versions |\n"
          "| --- | ---: | ---: | --- | --- |")
    for name, ds in sorted(fn.items(), key=lambda kv: -sum(d["self"] for d in kv[1]))[:a.top]:
        vals = [d["switches"] for d in ds]
        keys = sorted({k for v in vals for k in v})
        differ = [f"{c}.{f}" for c, f in keys if len({v.get((c, f)) for v in vals}) > 1]
        print(f"| {name} | {sum(d['self'] for d in ds):.1f} | {len(ds)} | {'yes' if ds[0]['parallel'] else ''} | "
              f"{', '.join(differ) or '-'} |")
    by_switch = defaultdict(lambda: [0.0, 0])
    for d in rec.done:
        for (c, f), on in d["switches"].items():
            by_switch[(c, f, on)][0] += d["self"]
            by_switch[(c, f, on)][1] += 1
    print("\n| switch | on: self CPU s (versions) | off: self CPU s (versions) |\n| --- | ---: | ---: |")
    for c, f in sorted({(c, f) for c, f, _ in by_switch}):
        on, off = by_switch[(c, f, True)], by_switch[(c, f, False)]
        print(f"| {c}.{f} | {on[0]:.1f} ({on[1]}) | {off[0]:.1f} ({off[1]}) |")
    if a.list:
        print("\n| case | function | self CPU s | switches on |\n| --- | --- | ---: | --- |")
        for d in rec.done:
            on = [f"{c}.{f}" for (c, f), v in d["switches"].items() if v]
            print(f"| {d['case']} | {d['name']} | {d['self']:.2f} | {', '.join(on)} |")
    from numba.core import types
    lit = [d for d in rec.done if any(isinstance(t, types.Literal) for t in d["args"])]
    print(f"\nversions specialised on a literal argument: {sum(d['self'] for d in lit):.1f} CPU s self "
          f"({len(lit)} versions: {', '.join(sorted({d['name'] for d in lit})) or '-'})")
    par = [d for d in rec.done if d["parallel"]]
    one = [d for d in par if d["case"].endswith("--threads 1")]
    print(f"parallel=True functions: {sum(d['self'] for d in par):.1f} CPU s self ({len(par)} versions) of "
          f"{compiling:.1f}; compiled by one-thread cases: {sum(d['self'] for d in one):.1f} ({len(one)} versions)")
    shutil.rmtree(CACHE, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
