"""The time per step against the rank count P: a model from measured per-rank costs (scripts/scaling_model.py,
docs/scaling.md).

The inputs are records of ``scripts/scaling.py`` at P = 1 (CPU-time phases,
list pairs, local particles, list builds), two or more sizes per dimension.
Fitted per dimension (least squares of the relative residuals over the sizes):

    pairs passes   (density + forces)          = a_p + c_p * pairs
    particle work  (sync + halo + integrate)   = a_n + c_n * local
    a list build   (rebuild / builds per step) = b_0 + b_n * local
    the rest of the step (Python)              = t_x

Per rank at P (the busiest rank: the most owned particles and ghosts):

    T(P) = t_0 + c_p Pi + c_n n_loc + (b_0 + b_n n_loc + [m_0 + m_n own + T_msg,b]) / s + T_msg(P),
    t_0 = a_p + a_n + t_x
    Pi    = p own + X                     (list pairs: p per particle, X crossing one slab boundary)
    n_loc = own + G + I                   (owned, ghosts, periodic images)
    T_msg = 2 alpha + 8 (3 d + 1) G / B + max(0, ceil(log2 P) alpha_ar - t_d)   (P >= 2; P = 1: in t_0)
    t_d   = d_share c_p Pi                 (the density pass, which the step's all-reduce runs behind)
    T_msg,b = 4 alpha + 8 (7 + 3 d) G / B + ceil(log2 P) alpha_ar         (the build's rounds)
    [...]: P >= 2 only; m_0, m_n fitted from records at P = 2 (migration's Python, outside MPI waits)

p, X, G and I are counted on the initial lattice (``Case``); s (steps per
list build) is a stated input per case. The build's own messages (one
all-reduce, a migration round and a ghost round of 7 + 3d floats per ghost,
each round after a round of row counts) are added to the build when P >= 2. Threads (beyond the slab limit)
share the pair passes only, which then cost ``thread_factor`` times more
work; the rest of the step stays on one thread.
"""
import json
import math

import numpy as np

from parsph.parallel import slabs
from parsph.physics.kernels import get_kernel
from parsph.setup import config
from parsph.sph.cells import grid_for
from . import builders
from .fits import relative_line


def load(path):
    """The records of a scaling.py JSON-lines file."""
    with open(path) as f:
        return [json.loads(line) for line in f if line.strip()]


def _paper_grid():
    """(cell rows per cutoff, the cutoff 2h + skin in lattice steps, wall layers) of the paper case."""
    cfg = config.build(builders.paper_run_file())
    grid = grid_for(cfg, get_kernel(cfg.kernel, cfg.dim))
    return grid.m, grid.cutoff / cfg.dx, cfg.layers


M, RC, LAYERS = _paper_grid()   # 2, 3.0 (h = 1.25 dx, skin 0.4 h), 3 (covering 2h = 2.5 dx)


def lattice_pairs(nx, nz, dim):
    """(pairs per particle p, pairs crossing a y plane between rows X) on the lattice of one y row.

    Columns: LAYERS wall columns, nx fluid, LAYERS wall (x not periodic); z
    periodic with nz rows (3-D). A pair is listed when |v| < RC lattice steps
    (half of those at exactly RC) and at least one member is fluid.
    """
    cols = nx + 2 * LAYERS
    fluid = np.zeros(cols, bool)
    fluid[LAYERS:LAYERS + nx] = True
    r = int(RC)
    per_row = cross = 0
    for i in range(-r, r + 1):
        for j in range(0, r + 1):
            for k in (range(-r, r + 1) if dim == 3 else (0,)):
                q = i * i + j * j + k * k
                if q > RC * RC or q == 0:
                    continue
                w = 0.5 if q == RC * RC else 1.0  # at exactly r_c: the flow's displacements put half inside
                if j == 0 and (i < 0 or (i == 0 and k < 0)):
                    continue  # the other half of the pairs in the row
                a = np.arange(max(0, -i), min(cols, cols - i))
                n_col = w * int((fluid[a] | fluid[a + i]).sum()) * nz
                per_row += n_col
                cross += j * n_col
    return per_row / (cols * nz), cross


class Case:
    """A Couette box on the lattice: N_x fluid columns over L, L_y (and L_z in 3-D) in lattice steps."""

    def __init__(self, name, dim, nx, ny, nz=1, L=0.01):
        self.name, self.dim, self.nx, self.ny, self.nz = name, dim, nx, ny, nz
        self.dx = L / nx
        self.Ly = ny * self.dx
        self.cutoff = RC * self.dx
        self.R = (nx + 2 * LAYERS) * nz        # particles per lattice row along y
        self.N = self.R * ny
        self.p, self.X = lattice_pairs(nx, nz, dim)

    @property
    def max_ranks(self):
        return slabs.max_ranks(self.Ly, self.cutoff, M)

    def per_rank(self, P):
        """(own, ghosts, images, pairs) of the busiest rank with P slabs (rows counted at their centres)."""
        side, ny_c = slabs.rows_of_length(self.Ly, self.cutoff, M)
        b = slabs.slab_bounds(self.Ly, P)
        first, last = slabs.cell_rows(b, side, ny_c)
        rows = lambda lo, hi: (math.ceil(hi / self.dx - 0.5 - 1e-9)  # noqa: E731
                               - math.ceil(lo / self.dx - 0.5 - 1e-9))
        worst = None
        for r in range(P):
            own = rows(b[r], b[r + 1]) * self.R
            g = (rows((first[r] - M) * side, b[r]) + rows(b[r + 1], (last[r] + M + 1) * side)) * self.R
            images = 0
            if self.dim == 3:
                nz_c = max(1, int(math.floor(M * self.nz / RC * (1 + 1e-12))))
                images = round((own + g) * 2 * M / nz_c)
            pairs = self.p * own + self.X
            key = (own + g, own)
            if worst is None or key > worst[0]:
                worst = (key, (own, g, images, pairs))
        return worst[1]


def fit(records, fixed=None):
    """The per-unit costs of one dimension from scaling.py records at P = 1 (two or more sizes).

    ``fixed``: take the intercepts (a_p, a_n, b_0, t_x) from these costs
    (another dimension's: the Python per step and per build is the same)
    and fit only the slopes.
    """
    rows = []
    for rec in records:
        r = rec["per_rank"][0]
        ph = r["phases_cpu_s"]
        per_build = ph.get("rebuild", 0.0) * rec["steps_per_rebuild"]
        rest = r["cpu_s_per_step"] - sum(ph.values())
        rows.append((r["pairs"], r["local"], ph["density"] + ph["forces"],
                     ph["sync"] + ph.get("halo", 0.0) + ph["integrate"], per_build, rest,
                     ph["density"] / (ph["density"] + ph["forces"])))
    a = np.array(rows)
    f = fixed or {}  # least squares of the relative residuals (the sizes span 100x)
    c_p, a_p = relative_line(a[:, 0], a[:, 2], f.get("a_p"))
    c_n, a_n = relative_line(a[:, 1], a[:, 3], f.get("a_n"))
    b_n, b_0 = relative_line(a[:, 1], a[:, 4], f.get("b_0"))
    t_x = f.get("t_x", float(a[:, 5].mean()))
    return {"c_p": c_p, "a_p": a_p, "c_n": c_n, "a_n": a_n, "b_0": b_0, "b_n": b_n, "t_x": t_x,
            "t_0": a_p + a_n + t_x, "d_share": float(a[:, 6].mean())}


def fit_migration(records):
    """Migration CPU per list build outside MPI waits (P >= 2 only: one rank migrates nothing) = m_0 + m_n own."""
    own, cost = [], []
    for rec in records:
        for x in rec["per_rank"]:
            busy = x["ring_cpu_s"]["migrate"] - x["blocked_cpu_by_phase_s"].get("migrate", 0.0)
            own.append(x["own"])
            cost.append(busy * rec["steps_per_rebuild"])
    m_n, m_0 = relative_line(own, cost)
    return {"m_0": m_0, "m_n": m_n}


def step_time(case, P, k, s, alpha, bandwidth, alpha_ar, threads=1):
    """Seconds per step of the busiest rank, and its parts; ``threads`` share the pair passes (Amdahl).

    With threads the pair passes cost ``k["thread_factor"]`` times more work
    (the threaded loops store each pair's values and gather them per
    particle); everything else stays on one thread.
    """
    own, g, images, pairs = case.per_rank(P)
    n_loc = own + g + images
    d = case.dim
    pair_work = k["c_p"] * pairs * (k["thread_factor"] / threads if threads > 1 else 1.0)
    msg = 0.0
    build = k["b_0"] + k["b_n"] * n_loc
    if P >= 2:
        stages = math.ceil(math.log2(P))
        hidden = min(stages * alpha_ar, k["d_share"] * pair_work)  # the all-reduce runs behind Eq. (3)
        msg = 2 * alpha + 8 * (3 * d + 1) * g / bandwidth + stages * alpha_ar - hidden
        build += k["m_0"] + k["m_n"] * own    # migration (strays sorted, rows packed, removed and added)
        build += 4 * alpha + 8 * (7 + 3 * d) * g / bandwidth + stages * alpha_ar  # its messages, ghosts
    compute = k["t_0"] + pair_work + k["c_n"] * n_loc
    return {"P": P, "own": own, "ghosts": g, "images": images, "pairs": pairs, "n_loc": n_loc,
            "compute": compute, "build": build / s, "messages": msg, "total": compute + build / s + msg}


def table(rows, t1, strong):
    out = ["| cores | ranks x threads | owned | ghosts | list pairs | compute [ms] | list builds [ms] "
           "| messages [us] | step [ms] | efficiency |", "|" + " --- |" * 10]
    for cores, r, th, t in rows:
        if t is None:
            out.append(f"| {cores} | {r} x {th} | | | | | | | (more threads than a node's cores) | |")
            continue
        eff = t1 / (cores * t["total"]) if strong else t1 / t["total"]
        out.append(f"| {cores} | {r} x {th} | {t['own']:,} | {t['ghosts']:,} | {t['pairs']:,.0f} | "
                   f"{t['compute'] * 1e3:.4g} | {t['build'] * 1e3:.3g} | {t['messages'] * 1e6:.3g} | "
                   f"{t['total'] * 1e3:.4g} | {eff:.2f} |")
    return "\n".join(out)


CORES = (1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096)


def strong(case, k, s, net, cores_per_node):
    """Ranks up to the slab limit, then threads in each rank (up to a node's cores)."""
    limit = case.max_ranks
    rows = []
    for c in CORES:
        r = c if c <= limit else limit
        th = 1 if c <= limit else c // limit
        rows.append((r * th, r, th, step_time(case, r, k, s, threads=th, **net) if th <= cores_per_node else None))
    return table(rows, step_time(case, 1, k, s, **net)["total"], True), limit


def weak(make, k, s, net):
    t1 = step_time(make(1), 1, k, s, **net)["total"]
    return table([(c, c, 1, step_time(make(c), c, k, s, **net)) for c in CORES], t1, False)


def case_of(rec):
    """The lattice Case of a scaling.py record (bench.py's Couette box with its overrides)."""
    sets = dict(x.split("=", 1) for x in rec["set"])
    dim = int(sets.get("scene.dim", 2))
    nx = rec["nx"]
    dx = 0.01 / nx
    ny = round(rec["Ly"] / dx)
    nz = round(float(sets.get("domain.Lz", rec["Ly"])) / dx) if dim == 3 else 1
    return Case("record", dim, nx, ny, nz)


def counts(records):
    """Measured per-rank counts and messages (the busiest rank) beside the model's, one row per record."""
    out = ["| case | P | owned | ghosts (lattice) | images (lattice) | list pairs (lattice) | sends / step "
           "| bytes sent / step (8 (3d+1) G) | all-reduces / step | per build: sends, bytes, all-reduces | "
           "steps per build |", "|" + " --- |" * 11]
    for rec in records:
        c = case_of(rec)
        P, pr = rec["ranks"], rec["per_rank"]
        own, g, images, pairs = c.per_rank(P)
        steps, builds = rec["steps"], max(rec["rebuilds"], 1)

        def msg(keys, field, div):
            return max(sum(x["messages"].get(k, {}).get(field, 0) for k in keys) for x in pr) / div
        step_sends = msg(("forward.send", "refresh.send"), "calls", steps)
        step_bytes = msg(("forward.send", "refresh.send"), "bytes", steps)
        gmax = max(x["ghosts_below"] + x["ghosts_above"] for x in pr)
        b_sends = msg(("migrate.send", "exchange_ghosts.send"), "calls", builds)
        b_bytes = msg(("migrate.send", "exchange_ghosts.send"), "bytes", builds)
        b_ar = msg(("migrate.allreduce",), "calls", builds)
        name = f"{c.dim}-D N_x={c.nx} L_y={rec['Ly']:g}"
        out.append(f"| {name} | {P} | {max(x['own'] for x in pr):,} | {gmax:,} ({g:,}) | "
                   f"{max(x['images'] for x in pr):,} ({images:,}) | {max(x['pairs'] for x in pr):,} ({pairs:,.0f}) | "
                   f"{step_sends:g} | {step_bytes:,.0f} ({8 * (3 * c.dim + 1) * gmax:,}) | "
                   f"{msg(('step.allreduce',), 'calls', steps):g} | {b_sends:g}, {b_bytes:,.0f}, {b_ar:g} | "
                   f"{rec['steps_per_rebuild']:.1f} |")
    return "\n".join(out)


def fitted(k2, k3, paths2d, paths3d):
    """The table of the fitted records: CPU per step measured and modelled."""
    out = ["| fitted record | N_x | list pairs | local | steps per build | CPU per step, measured [ms] | model [ms] |",
           "| --- | --- | --- | --- | --- | --- | --- |"]
    for dim, k, paths in ((2, k2, paths2d), (3, k3, paths3d)):
        for rec in (r for path in paths for r in load(path)):
            x = rec["per_rank"][0]
            model = (k["t_0"] + k["c_p"] * x["pairs"] + k["c_n"] * x["local"]
                     + (k["b_0"] + k["b_n"] * x["local"]) / rec["steps_per_rebuild"])
            out.append(f"| {dim}-D | {rec['nx']} | {x['pairs']:,} | {x['local']:,} | {rec['steps_per_rebuild']:.1f} | "
                       f"{x['cpu_s_per_step'] * 1e3:.3f} | {model * 1e3:.3f} |")
    return "\n".join(out)


def inputs_table(k2, k3):
    """The model's inputs in 2-D and 3-D."""
    out = ["| input | 2-D | 3-D |", "| --- | --- | --- |"]
    for key, unit, scale in (("c_p", "ns per list pair (density + forces)", 1e9),
                             ("c_n", "ns per local particle (sync, ghost rho, integration)", 1e9),
                             ("t_0", "us fixed per step (a_p + a_n + t_x)", 1e6),
                             ("b_0", "us fixed per list build", 1e6), ("b_n", "ns per local particle per build", 1e9),
                             ("m_0", "us fixed per build for the migration (P >= 2)", 1e6),
                             ("m_n", "ns per owned particle per build for the migration", 1e9),
                             ("thread_factor", "pair-pass work with threads / without", 1.0)):
        out.append(f"| {key}: {unit} | {k2[key] * scale:.4g} | {k3[key] * scale:.4g} |")
    return "\n".join(out)


def thread_ratios(paths):
    """The ratios of the pair passes' CPU per pair with 2 threads to 1, from pairs of records."""
    per_pair = []
    for path in paths:
        for rec in load(path):
            x = rec["per_rank"][0]
            per_pair.append((x["phases_cpu_s"]["density"] + x["phases_cpu_s"]["forces"]) / x["pairs"])
    return [two / one for one, two in zip(per_pair[0::2], per_pair[1::2])]


def check(paths, k2, alpha_here, bandwidth):
    """The model against records of the paper case (P = 1, 2): lines per record, then per P."""
    paper = Case("paper", 2, 50, 50)
    lines, summary = [], {}
    for path in paths:
        for rec in load(path):
            P = rec["ranks"]
            here = dict(alpha=alpha_here, bandwidth=bandwidth, alpha_ar=alpha_here)
            t = step_time(paper, P, k2, rec["steps_per_rebuild"], **here)
            pr = rec["per_rank"]
            busy = max(x["cpu_s_per_step"] - x["blocked_cpu_s_per_step"] for x in pr)
            alone = max(x["alone_blocked_s"] for x in pr)
            x = max(pr, key=lambda x: x["cpu_s_per_step"] - x["blocked_cpu_s_per_step"])
            ph, bl = x["phases_cpu_s"], x["blocked_cpu_by_phase_s"]
            parts = {"pairs": ph["density"] + ph["forces"],
                     "particles": ph["sync"] + ph["halo"] + ph["integrate"] - bl.get("forward", 0)
                     - bl.get("refresh", 0) - bl.get("step", 0),
                     "build": ph.get("rebuild", 0) - bl.get("migrate", 0) - bl.get("exchange_ghosts", 0),
                     "rest": x["cpu_s_per_step"] - sum(ph.values())}
            n_loc = t["n_loc"]
            model = {"pairs": k2["a_p"] + k2["c_p"] * t["pairs"], "particles": k2["a_n"] + k2["c_n"] * n_loc,
                     "build": t["build"], "rest": k2["t_x"]}
            lines.append("   parts (model / measured, ms): " + ", ".join(
                f"{k} {model[k] * 1e3:.3f} / {parts[k] * 1e3:.3f}" for k in parts) +
                f", messages {t['messages'] * 1e3:.3f} / {alone * 1e3:.3f} (lone step, blocked)")
            summary.setdefault(P, []).append((t["total"], busy + alone, rec["step_best_block_s"]))
            lines.append(f"check {path} P={P}: model {t['total'] * 1e3:.3f} ms (own {t['own']}, ghosts {t['ghosts']}, "
                         f"pairs {t['pairs']:.0f}); measured: own {max(x['own'] for x in pr)} ghosts "
                         f"{max(x['ghosts_below'] + x['ghosts_above'] for x in pr)} "
                         f"pairs {max(x['pairs'] for x in pr)}, "
                         f"CPU {rec['cpu_s_per_step_max'] * 1e3:.3f} ms, outside waits + lone messages "
                         f"{(busy + alone) * 1e3:.3f} ms, fastest block {rec['step_best_block_s'] * 1e3:.3f} ms, "
                         f"s = {rec['steps_per_rebuild']:.1f}")
    for P, rows in sorted(summary.items()):
        model = rows[0][0]
        busy = float(np.median([r[1] for r in rows]))
        wall = float(np.median([r[2] for r in rows]))
        lines.append(f"check P={P}, {len(rows)} runs: model {model * 1e3:.3f} ms; median measured: outside waits + "
                     f"lone messages {busy * 1e3:.3f} ms (model {100 * (model / busy - 1):+.0f}%), fastest block "
                     f"{wall * 1e3:.3f} ms (model {100 * (model / wall - 1):+.0f}%)")
    return lines
