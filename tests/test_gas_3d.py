"""The solved gas in 3-D (docs/physics.md, "The solved gas"): the grid's z periodic, its cells deposited and
interpolated trilinearly, the finite volumes with faces across z.

- the solve against independent forms: a 3-D grid whose K and V do not vary along z is the 2-D solve in
  every layer (no flux across z); layers in series along the periodic z carry the flux sum(V/K) / sum(1/K)
  (the ring's pressure returns to itself); layers in parallel driven by a mean flux U along a periodic x
  carry K_k U / mean(K) each;
- the deposit: a lattice filling the box deposits its theta in every cell (the plates' folding, y and z
  wrapping); volume and momentum conserved, the same bits in any order; the interpolation its transpose; a
  linear field interpolated exactly.
The scenes on 1, 2 and 3 ranks: tests/test_mpi_scenes.py (``fluidized_bed_solved_3d``)."""
import numpy as np
import pytest

from parsph.gas import darcy, deposit
from parsph.sph.particles import GRAIN


def _sides(ny, nz=1, U=None):
    U = np.linspace(0.02, 0.07, ny) if U is None else U
    return (darcy.Side("flux", np.repeat(U, nz)), darcy.Side("pressure", 0.0))


@pytest.mark.parametrize("closed_y", [False, True])
def test_a_grid_uniform_along_z_solves_as_the_2d_grid_in_every_layer(closed_y):
    rng = np.random.default_rng(3)
    nx, ny, nz, hx, hy, hz = 7, 5, 3, 0.2, 0.3, 0.25
    K = rng.uniform(0.1, 5.0, (nx, ny))
    V = rng.normal(size=(nx, ny, 2)) * 0.01
    y2 = (darcy.Side("flux", np.zeros(nx)),) * 2 if closed_y else None
    y3 = (darcy.Side("flux", np.zeros(nx * nz)),) * 2 if closed_y else None
    flat = darcy.solve(K, V, hx, hy, _sides(ny), y2)
    K3 = np.repeat(K[:, :, None], nz, axis=2)
    V3 = np.concatenate([np.repeat(V[:, :, None, :], nz, axis=2), np.zeros((nx, ny, nz, 1))], axis=3)
    deep = darcy.solve(K3, V3, hx, hy, _sides(ny, nz), y3, hz=hz)
    assert deep.p.shape == (nx, ny, nz) and deep.jz.shape == (nx, ny, nz + 1)
    scale = np.abs(flat.p).max()
    for k in range(nz):
        np.testing.assert_allclose(deep.p[:, :, k], flat.p, rtol=0, atol=1e-11 * scale)
        np.testing.assert_allclose(deep.jx[:, :, k], flat.jx, rtol=0, atol=1e-12)
        np.testing.assert_allclose(deep.jy[:, :, k], flat.jy, rtol=0, atol=1e-12)
    assert np.abs(deep.jz).max() < 1e-12
    assert deep.centred().shape == (nx, ny, nz, 3)


def test_layers_in_series_along_the_periodic_z():
    """K and the solids' V_z varying along z alone, no flux through the plates (p' pinned): the mixture's flux
    across z is one number, sum_k (V_k / K_k) / sum_k (1 / K_k) (the pressure drops (j - V_k) h / K_k around
    the ring sum to zero), and nothing flows along x or y."""
    rng = np.random.default_rng(8)
    nx, ny, nz, h = 3, 4, 9, 0.1
    Kz = rng.uniform(0.2, 4.0, nz)
    Vz = rng.normal(size=nz)
    K = np.broadcast_to(Kz, (nx, ny, nz)).copy()
    V = np.zeros((nx, ny, nz, 3))
    V[..., 2] = Vz
    closed = (darcy.Side("flux", 0.0), darcy.Side("flux", 0.0))
    sol = darcy.solve(K, V, h, h, closed, None, hz=h)
    j = (Vz / Kz).sum() / (1.0 / Kz).sum()
    np.testing.assert_allclose(sol.jz, j, rtol=1e-10)
    assert np.abs(sol.jx).max() < 1e-12 * np.abs(Vz).max() and np.abs(sol.jy).max() < 1e-12 * np.abs(Vz).max()


def test_layers_in_parallel_driven_by_a_mean_flux():
    """x periodic, fed at the mean flux U per unit area of its cross-sections, K varying along z alone: each
    layer carries K_k G with G = U / mean(K), and nothing crosses z."""
    rng = np.random.default_rng(2)
    nx, ny, nz, U = 4, 3, 5, 0.3
    Kz = rng.uniform(0.5, 2.0, nz)
    K = np.broadcast_to(Kz, (nx, ny, nz)).copy()
    sol = darcy.solve(K, np.zeros((nx, ny, nz, 3)), 0.1, 0.2, None, None, mean_flux=U, hz=0.15)
    np.testing.assert_allclose(sol.jx, np.broadcast_to(Kz * U / Kz.mean(), sol.jx.shape), rtol=1e-10)
    assert np.abs(sol.jz).max() < 1e-12 and np.abs(sol.jy).max() < 1e-12


# the band (half-width ny nz), and SuperLU ordered by minimum degree where the band is too wide (or too big)
@pytest.mark.parametrize("nx, ny, nz, band_max", [(9, 6, 5, None), (6, 8, 4, 16)])
def test_random_3d_fields_have_no_divergence_and_two_solvers_agree(nx, ny, nz, band_max, monkeypatch):
    if band_max is not None:
        monkeypatch.setattr(darcy, "BAND_MAX_3D", band_max)
    rng = np.random.default_rng(12)
    h = (0.1, 0.15, 0.12)
    K = rng.uniform(0.01, 10.0, (nx, ny, nz))
    V = rng.normal(size=(nx, ny, nz, 3))
    sides = (darcy.Side("flux", rng.uniform(0, 1, ny * nz)), darcy.Side("pressure", 0.0))
    d = darcy.Darcy(nx, ny, h[0], h[1], sides, None, nz=nz, hz=h[2])
    assert d.width == ny * nz and d.banded == (band_max is None) and d.ordered == (band_max is not None)
    sol = d.solve(K, V)
    div = ((sol.jx[1:] - sol.jx[:-1]) / h[0] + (sol.jy[:, 1:] - sol.jy[:, :-1]) / h[1]
           + (sol.jz[:, :, 1:] - sol.jz[:, :, :-1]) / h[2])
    assert np.abs(div).max() < 1e-11 * np.abs(V).max() / min(h)
    lu = darcy.Darcy(nx, ny, h[0], h[1], sides, None, nz=nz, hz=h[2])
    lu.banded = lu.ordered = False  # the same matrix through SuperLU, its default column order
    other = lu.solve(K, V)
    assert np.allclose(sol.p, other.p, rtol=1e-10, atol=1e-12 * np.abs(sol.p).max())


# ---- the deposit in 3-D ---------------------------------------------------------------------------------
BOX = (5, 4, 3, 0.5, 0.4, 0.3)  # nx, ny, nz, Lx, Ly, Lz


def _places(pos, kind):
    """The particles' cells and weights on BOX's grid (deposit.weights)."""
    nx, ny, nz, Lx, Ly, Lz = BOX
    cells, w = np.zeros((len(pos), 6), np.int32), np.zeros((len(pos), 6))
    deposit.weights(pos, kind, len(pos), nx, ny, nz, Lx / nx, Ly / ny, Lz / nz, Lx, Ly, Lz, True, False, Ly, cells, w)
    return cells, w


def _deposit(pos, vel, mass, kind, rho_s=2000.0):
    nx, ny, nz, Lx, Ly, Lz = BOX
    out = np.zeros((nx, ny, nz, 5), np.int64)
    rates = np.abs(vel[:, 0]) * 100.0  # any drag rates [1/s]
    deposit.deposit(*_places(pos, kind), vel, mass, len(mass), rho_s, Lx / nx, Ly / ny, Lz / nz, out, rates,
                    np.zeros(len(mass)), 30.0)
    return out


def _interpolate(pos, kind, field):
    at = np.zeros((len(pos), field.shape[-1]))
    deposit.interpolate(*_places(pos, kind), len(pos), field, at)
    return at


def _particles(n, seed):
    nx, ny, nz, Lx, Ly, Lz = BOX
    rng = np.random.default_rng(seed)
    pos = np.column_stack([rng.uniform(-0.05 * Lx, 1.05 * Lx, n), rng.uniform(-0.3 * Ly, 1.3 * Ly, n),
                           rng.uniform(-0.3 * Lz, 1.3 * Lz, n)])
    vel = rng.normal(size=(n, 3))
    mass = rng.uniform(0.5, 1.5, n) * 1e-3
    kind = np.where(rng.random(n) < 0.9, GRAIN, 1).astype(np.int64)
    return pos, vel, mass, kind


def test_a_lattice_filling_the_box_deposits_its_theta_in_every_cell():
    nx, ny, nz, Lx, Ly, Lz = BOX
    rho_s, theta0, d = 2000.0, 0.3, Lx / nx / 4
    axes = [(np.arange(4 * n) + 0.5) * d for n in (nx, ny, nz)]
    pos = np.stack([a.ravel() for a in np.meshgrid(*axes, indexing="ij")], axis=1)
    n = len(pos)
    sums = _deposit(pos, np.zeros((n, 3)), np.full(n, rho_s * theta0 * d ** 3), np.zeros(n, np.int64), rho_s)
    np.testing.assert_allclose(sums[..., 0] / deposit.SCALE, theta0, rtol=0, atol=1e-9)
    at = _interpolate(pos, np.zeros(n, np.int64), np.full((nx, ny, nz, 1), 2.5))
    np.testing.assert_allclose(at[:, 0], 2.5, rtol=1e-14)


def test_deposit_conserves_volume_and_drag_and_interpolation_is_its_transpose():
    nx, ny, nz, Lx, Ly, Lz = BOX
    rho_s = 2000.0
    pos, vel, mass, kind = _particles(500, 4)
    sums = _deposit(pos, vel, mass, kind, rho_s)
    fluid = kind == GRAIN
    vol = (Lx / nx) * (Ly / ny) * (Lz / nz)
    rounding = 8 * fluid.sum() * 0.5 / deposit.SCALE * vol  # each of the 8 terms a particle adds rounds once
    assert abs(sums[..., 0].sum() / deposit.SCALE * vol - (mass[fluid] / rho_s).sum()) <= rounding
    C = 100.0 * np.abs(vel[fluid, 0])
    _, R, V_R = deposit.cells_of(sums, rho_s, 30.0)
    assert V_R.shape == (nx, ny, nz, 3)
    r_rounding = 8 * fluid.sum() * 0.5 / deposit.RATE_SCALE * rho_s * 30.0 * vol
    assert abs(R.sum() * vol - (mass[fluid] * C).sum()) <= r_rounding
    for c in range(3):
        assert abs((R * V_R[..., c]).sum() * vol - (mass[fluid] * C * vel[fluid, c]).sum()) <= r_rounding * 10
    perm = np.random.default_rng(9).permutation(len(mass))
    assert np.array_equal(sums, _deposit(pos[perm], vel[perm], mass[perm], kind[perm], rho_s))
    f = np.random.default_rng(1).normal(size=(nx, ny, nz, 1))
    at = _interpolate(pos, kind, f)
    lhs = (mass[fluid] / rho_s * at[fluid, 0]).sum()
    assert lhs == pytest.approx((f[..., 0] * sums[..., 0] / deposit.SCALE).sum() * vol, rel=1e-10)
    assert np.all(at[~fluid] == 0.0)


def test_linear_fields_are_interpolated_exactly_inside():
    nx, ny, nz, Lx, Ly, Lz = BOX
    c = [(np.arange(n) + 0.5) * L / n for n, L in ((nx, Lx), (ny, Ly), (nz, Lz))]
    X, Y, Z = np.meshgrid(*c, indexing="ij")
    f = (2.0 * X - 3.0 * Y + 0.5 * Z + 1.0)[..., None]
    rng = np.random.default_rng(0)
    pos = np.column_stack([rng.uniform(a[0], a[-1], 60) for a in c])
    at = _interpolate(pos, np.zeros(60, np.int64), f)
    np.testing.assert_allclose(at[:, 0], 2.0 * pos[:, 0] - 3.0 * pos[:, 1] + 0.5 * pos[:, 2] + 1.0, rtol=0,
                               atol=1e-12)


# ---- a 3-D bed's outputs ----------------------------------------------------------------------------------
def test_a_3d_bed_writes_its_grid_and_paraview_draws_it_as_a_3d_mesh(tmp_path):
    """A short 3-D bed in the solved gas: /grid holds theta (nx, ny, nz) whose sum times the cell volume is the
    grains' volume, j and u_g (nx, ny, nz, 3); the sidecar's gas grid is a 3DSMesh over nodes (i h_x, j h_y,
    k h_z) placed upright as the particles ((y, x, z)); ``parsph check`` reports it with its 3-D measures."""
    import xml.etree.ElementTree as ET
    import h5py
    from mpi4py import MPI
    from parsph.simulation.case import run_case
    from parsph.studies import layers
    cfg = layers.load(layers.BED, ['gas.flow="solved"', "scene.dim=3", "body_force.g=[-9.81, 0.0, 0.0]",
                                   "domain.L=0.004", "numerics.Nx=20", "domain.Ly=0.0024", "domain.Lz=0.0012",
                                   "gas.cell=0.0004", "scene.height=0.0016", "numerics.dt=5e-5",
                                   "output.t_end=0.002", "output.times=[0.002]", "output.snapshots=true"])
    run_case(MPI.COMM_SELF, cfg, str(tmp_path), "bed")
    with h5py.File(tmp_path / "bed_0000.h5", "r") as f:
        g = f["grid"]
        hx, hy, hz = g.attrs["cell"]
        theta = g["theta"][()]
        fluid = f["particles/kind"][()] == 0
        volume = f["particles/mass"][()][fluid].sum() / cfg.rho_s
        assert theta.shape == (10, 6, 3)
        assert theta.sum() * hx * hy * hz == pytest.approx(volume, rel=1e-9)
        assert g["j"].shape == g["u_g"].shape == g["u_g_xyz"].shape == theta.shape + (3,)
        view, u = g["u_g_xyz"][()], g["u_g"][()]
        assert np.array_equal(view[..., 0], u[..., 1]) and np.array_equal(view[..., 2], u[..., 2])
    dom = ET.parse(tmp_path / "bed.xdmf").getroot().find("Domain")
    (gas,) = [x for x in dom.findall("Grid") if x.get("Name") == "gas grid"]
    topo = gas.find("Grid/Topology")
    assert topo.get("TopologyType") == "3DSMesh" and topo.get("Dimensions") == "11 7 4"
    assert gas.find("Grid/Geometry").get("GeometryType") == "XYZ"
    with h5py.File(tmp_path / "bed.cells.h5", "r") as f:
        nodes = f["grid_nodes"][()].reshape(11, 7, 4, 3)
    assert np.allclose(nodes[:, 0, 0, 1], np.arange(11) * hx) and np.allclose(nodes[0, :, 0, 0], np.arange(7) * hy)
    assert np.allclose(nodes[0, 0, :, 2], np.arange(4) * hz)


# ---- the band split in two ---------------------------------------------------------------------------------
@pytest.mark.parametrize("shape", [(12, 9), (9, 6, 4)])
def test_the_split_band_solves_as_the_whole_band(shape):
    """Two blocks and a separator (parsph.gas.split_band) against the whole banded Cholesky: the same p' to
    1e-10, on a random field (2-D: the ring of y folded in each row; 3-D: y and z periodic)."""
    rng = np.random.default_rng(21)
    nx, ny = shape[:2]
    nz = shape[2] if len(shape) == 3 else 1
    K = rng.uniform(0.01, 10.0, shape)
    V = rng.normal(size=shape + (len(shape),))
    sides = (darcy.Side("flux", rng.uniform(0, 1, ny * nz)), darcy.Side("pressure", 0.0))
    whole = darcy.Darcy(nx, ny, 0.1, 0.15, sides, None, nz=nz, hz=0.12, method="band").solve(K, V)
    d = darcy.Darcy(nx, ny, 0.1, 0.15, sides, None, nz=nz, hz=0.12, method="split")
    split = d.solve(K, V)
    assert d.split and d.factorisations == 1
    assert np.allclose(split.p, whole.p, rtol=1e-10, atol=1e-12 * np.abs(whole.p).max())
    assert np.allclose(split.jx, whole.jx, rtol=1e-9, atol=1e-12)


def test_a_wide_band_is_split_and_a_narrow_one_is_not():
    sides = (darcy.Side("flux", 0.5), darcy.Side("pressure", 0.0))
    assert darcy.Darcy(80, 160, 1e-3, 1e-3, sides, None).split           # the 50,000-particle bed's grid
    assert not darcy.Darcy(80, 40, 1e-3, 1e-3, sides, None).split        # run/bubbling_bed.toml's
    assert not darcy.Darcy(20, 10, 1e-3, 1e-3, sides, None, nz=5, hz=1e-3).split  # run/bubbling_bed_3d.toml's
