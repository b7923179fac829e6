"""Output and restart I/O measured (scripts/io_bench.py, docs/io.md): the real writer and the slab reader
against the raw disk, and the markdown tables of the records.

The writer is timed on synthetic particles of the paper case's lattice (no
solver), each rank holding the lattice rows of its slab, shuffled in memory by
default (the worst case for the writer's y-bin sort); the raw rates (numpy
write + fsync and ``dd oflag=direct``; numpy read and ``dd iflag=direct`` of
files evicted from the page cache) say what the disk allows, so the ratio
writer / raw is the writer's own overhead.
"""
import json
import os
import platform
import shutil
import statistics
import subprocess
import tempfile
import time

import numpy as np

from parsph import output
from parsph.setup import config
from parsph.setup.scenes import lattice
from parsph.sph.particles import MOVING_WALL
from .builders import paper_run_file
from .machine import REPO, cpu_model


def paper_lattice():
    """The paper case's run (Table 1): N = N_y (N_x + 2 layers) particles in rows of dy = dx."""
    return config.build(paper_run_file())


def machine():
    """The machine and the disk measured (that of the checkout), as the I/O records name them."""
    model = cpu_model()
    disk = subprocess.run(["df", "-hT", str(REPO)], capture_output=True, text=True).stdout.splitlines()[-1:]
    return {"host": platform.node(), "cores": os.cpu_count(), "cpu": model, "disk": " ".join(disk[0].split()[:3])
            if disk else "?", "mem_gb": round(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 1e9, 1)}


def ly_for(n):
    """L_y of the paper lattice with at least n particles (a whole number of rows)."""
    cfg = paper_lattice()
    per_row = cfg.Nx + 2 * cfg.layers
    rows = -(-n // per_row)
    return rows * cfg.dx, rows * per_row


def evict(path):
    """Drop the (clean, fsynced) pages of ``path`` from the page cache."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
        os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
    finally:
        os.close(fd)


def dd_rate(args, nbytes):
    t0 = time.perf_counter()
    r = subprocess.run(["dd", *args, "bs=4M", f"count={-(-nbytes // (4 << 20))}", "status=none"],
                       capture_output=True, text=True)
    if r.returncode:
        return float("nan")
    return (-(-nbytes // (4 << 20))) * (4 << 20) / (time.perf_counter() - t0)


def raw_rates(d, nbytes):
    """numpy write+fsync, dd oflag=direct; numpy read and dd iflag=direct of evicted files [B/s]."""
    path = os.path.join(d, "raw.bin")
    buf = np.random.default_rng(0).integers(0, 255, nbytes, dtype=np.uint8)
    t0 = time.perf_counter()
    with open(path, "wb") as fh:
        buf.tofile(fh)
        fh.flush()
        os.fsync(fh.fileno())
    w_np = nbytes / (time.perf_counter() - t0)
    evict(path)
    t0 = time.perf_counter()
    back = np.fromfile(path, dtype=np.uint8)
    r_np = nbytes / (time.perf_counter() - t0)
    assert back.size == nbytes
    del back
    os.remove(path)
    w_dd = dd_rate(["if=/dev/zero", f"of={path}", "oflag=direct"], nbytes)
    evict(path)
    r_dd = dd_rate([f"if={path}", "of=/dev/null", "iflag=direct"], nbytes)
    os.remove(path)
    return {"write_numpy": w_np, "write_dd_direct": w_dd, "read_numpy": r_np, "read_dd_direct": r_dd}


def throughput(args):
    """Write and read back ``args.n`` particles on COMM_WORLD ``args.repeat`` times in ``args.dir``; rank 0
    prints the medians (and writes them to ``args.json``)."""
    from mpi4py import MPI  # here: the report reads files and starts no MPI
    comm = MPI.COMM_WORLD
    P, rank = comm.size, comm.rank
    Ly, N = ly_for(args.n)
    cfg = config.build(paper_run_file().set("domain", Ly=Ly))
    # rank r: the lattice rows of its slab, as the solver would own them
    rows = cfg.Ny
    r0, r1 = rank * rows // P, (rank + 1) * rows // P
    lo, hi = r0 * cfg.dy, r1 * cfg.dy
    gid, kind, mass, pos, _ = lattice(cfg, lo, hi, right_wall=MOVING_WALL)
    n = len(gid)
    rng = np.random.default_rng(rank)
    fields = {"id": gid, "kind": kind, "mass": mass, "position": pos, "velocity": rng.normal(size=(n, 2)),
              "theta": rng.uniform(0.3, 0.4, n)}
    if args.order == "shuffled":  # the worst case for the writer's y-bin sort
        perm = rng.permutation(n)
        fields = {k: v[perm] for k, v in fields.items()}
        gid = np.sort(gid)
    prof = {k: np.zeros(cfg.Nx) for k in ("x", "vy", "theta", "count", "vy_exact", "theta_exact")}
    prof["err"] = (0.0, 0.0)
    d = comm.bcast(tempfile.mkdtemp(prefix="io_bench_", dir=args.dir) if rank == 0 else None)
    rounds = []
    for k in range(args.repeat):
        out = output.Output(comm, d, f"bench{k}", cfg, N)
        frame = output.Frame(0.0, 0, cfg.dt, prof, fields)
        comm.Barrier()
        t0 = time.perf_counter()
        path = out(frame, snapshot=True)
        comm.Barrier()
        t_write = time.perf_counter() - t0
        size = os.path.getsize(path)
        evict(path)
        comm.Barrier()
        t0 = time.perf_counter()
        got = output.read_particles(path, comm, lo, hi)
        comm.Barrier()
        t_read = time.perf_counter() - t0
        assert np.array_equal(np.sort(got["id"]), gid)
        read_bytes = comm.allreduce(sum(a.nbytes for a in got.values()))
        del got
        raw = raw_rates(d, size) if rank == 0 else None
        rounds.append({"write_s": t_write, "file_bytes": size, "write": size / t_write,
                       "read_s": t_read, "read_bytes": read_bytes, "read": read_bytes / t_read, "raw": raw})
        if rank == 0:
            os.remove(path)
    if rank == 0:
        shutil.rmtree(d)

        def med(f):
            return statistics.median(f(r) for r in rounds)
        res = {"mode": "throughput", "ranks": P, "n": N, "repeat": args.repeat, "order": args.order,
               "machine": machine(), "load_avg": os.getloadavg(),
               "parallel_hdf5": output.parallel_hdf5_available(),
               "file_bytes": rounds[0]["file_bytes"], "read_bytes": rounds[0]["read_bytes"],
               "write_MBps": med(lambda r: r["write"]) / 1e6, "read_MBps": med(lambda r: r["read"]) / 1e6,
               "raw_MBps": {k: med(lambda r, k=k: r["raw"][k]) / 1e6 for k in rounds[0]["raw"]},
               "rounds": rounds}
        raw_w = max(res["raw_MBps"]["write_numpy"], res["raw_MBps"]["write_dd_direct"])
        raw_r = max(res["raw_MBps"]["read_numpy"], res["raw_MBps"]["read_dd_direct"])
        res["write_ratio"] = res["write_MBps"] / raw_w
        res["read_ratio"] = res["read_MBps"] / raw_r
        print(json.dumps({k: v for k, v in res.items() if k != "rounds"}, indent=1))
        if args.json:
            with open(args.json, "w") as f:
                json.dump(res, f, indent=1)


def report(paths):
    """Markdown tables of result files (throughput and rss JSON)."""
    rows, rss_rows, machines = [], [], set()
    for p in paths:
        with open(p) as f:
            r = json.load(f)
        m = r["machine"]
        machines.add(f"{m['host']}: {m['cores']} cores ({m['cpu']}), {m['mem_gb']} GB, {m['disk']}")
        if r["mode"] == "throughput":
            rows.append(r)
        else:
            rss_rows.extend(r["rows"])
    out = [f"Machine: {'; '.join(sorted(machines))}.", ""]
    if rows:
        out += ["| N | P | file MB | write MB/s | read MB/s | raw write numpy / dd direct | raw read numpy / dd direct "
                "| write / raw (numpy, dd) | read / raw (numpy, dd) | load avg |",
                "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
        for r in sorted(rows, key=lambda r: (r["n"], r["ranks"])):
            raw = r["raw_MBps"]
            load = f"{r['load_avg'][0]:.1f}" if "load_avg" in r else "?"
            out.append(
                f"| {r['n'] / 1e6:.0f} M | {r['ranks']} | {r['file_bytes'] / 1e6:.0f} | {r['write_MBps']:.0f} "
                f"| {r['read_MBps']:.0f} | {raw['write_numpy']:.0f} / {raw['write_dd_direct']:.0f} "
                f"| {raw['read_numpy']:.0f} / {raw['read_dd_direct']:.0f} "
                f"| {r['write_MBps'] / raw['write_numpy']:.2f}, {r['write_MBps'] / raw['write_dd_direct']:.2f} "
                f"| {r['read_MBps'] / raw['read_numpy']:.2f}, {r['read_MBps'] / raw['read_dd_direct']:.2f} "
                f"| {load} |")
    if rss_rows:
        out += ["", "| N | P | fresh: peak RSS per rank [MB] | restart: peak RSS per rank [MB] "
                "| restart / fresh (max rank) |", "| --- | --- | --- | --- | --- |"]
        for r in rss_rows:
            fresh, rest = (", ".join(f"{v:.0f}" for v in r[k]["peak_rss_MB"]) for k in ("fresh", "restart"))
            out.append(f"| {r['n'] / 1e6:.0f} M | {r['ranks']} | {fresh} | {rest} | {r['ratio_max']:.3f} |")
    print("\n".join(out))


