"""The layer scenes against docs/physics.md's references 3 and 4 (parsph.physics.gas_references): short runs on one
rank, measured by parsph.studies.layers (the top: parsph.sph.projected.interface_height).

- a layer at rest without gas keeps its mass below the hydrostatic profile's top and its top within a few h
  of it;
- batch sedimentation at theta0 = 0.1, 0.15, 0.2: the interface (theta0 / 2 level) within 2% of H0 of
  Kynch's line until the fronts meet, the end state within 2% of the hydrostatic sediment (its height at
  theta0 / 2, relative to H0; the particles' theta from 2h above the floor to 2h below its half-floor level);
- bed expansion in water at theta* = 0.2, 0.3, 0.4 (Stokes) and in air (Gidaspow, run/fluidized_bed_air.toml):
  the particles' theta in the interior within 2% of the steady column's theta(x).

The runs use the midpoint integrator (its acoustic limit: steps ~10x longer than the paper scheme's
damping limit at the sediment's theta), dx = 0.2 mm and Ly = 0.8 mm (4 rows: 2h + skin fits).
"""
import numpy as np
import pytest

from parsph.studies import layers

MIDPOINT = 'numerics.integrator="midpoint"'


def test_a_layer_without_gas_stays_below_its_hydrostatic_top():
    """theta0 = 0.5 (the hydrostatic sediment's floor is 0.57), 5 mm, k = 1: no particle above the end state's
    top (its theta0/20 level) + 2h at any time, the top (theta0/2) within 2h of the end state's."""
    r = layers.free_surface(theta0=0.5, H0=0.005, t_end=0.3,
                            extra=[MIDPOINT, "domain.L=0.008", "numerics.Nx=40", "material.k=1.0"])
    h = r["h"]
    assert max(r["highest"]) < r["low_ref"] + 2 * h, r
    assert max(abs(t - r["top_ref"]) for t in r["top"]) < 2 * h, r
    assert max(abs(t - r["low_ref"]) for t in r["low"]) < 2 * h, r


# (theta0, H0): H0 large enough that the inertial lag v0 tau (tau = the drag's relaxation time, 6 ms at
# theta0 = 0.1) plus the front's ~h offset stay under 1.5% of H0
SEDIMENTATION = [(0.1, 0.02), (0.15, 0.015), (0.2, 0.01)]


@pytest.mark.parametrize("theta0,H0", SEDIMENTATION)
def test_batch_sedimentation_follows_kynch(theta0, H0):
    L = round(H0 * 1.2 / 2e-4) * 2e-4
    r = layers.sedimentation(theta0, H0=H0, Ly=8e-4, settle=1.5,
                             extra=[MIDPOINT, f"domain.L={L!r}", f"numerics.Nx={round(L / 2e-4)}",
                                    "checks.theta_change=6.0"])   # the sediment packs to 5 theta0 at 0.1
    errs = np.abs(r["interface_errors"])
    assert len(errs) == 6 and errs.max() < 0.02, r["interface_errors"]
    assert abs(r["end_height_errors"][-1]) < 0.02, r["end_height_errors"]
    assert r["end_profile_error"] < 0.02, r["end_profile_error"]
    assert r["interface"][-1] > r["meeting_height"]


# (theta*, theta0): from theta0 = 0.45 a bed fed to theta* = 0.2 lifts off the floor as a block (docs)
BEDS = [(0.2, 0.3), (0.3, 0.45), (0.4, 0.45)]


@pytest.mark.parametrize("theta_star,theta0", BEDS)
def test_bed_expands_to_the_steady_column(theta_star, theta0):
    r = layers.bed(theta_star=theta_star, H0=0.005, Ly=8e-4, t_end=1.5, n_times=3,
                   extra=[MIDPOINT, "domain.L=0.015", "numerics.Nx=75", f"material.theta0={theta0}"])
    assert abs(r["theta_star"] - theta_star) < 1e-9
    assert r["errors"][-1] < 0.02, r["errors"]
    assert abs(r["tops"][-1] - r["top_ref"]) < 2 * 2.5e-4, (r["tops"], r["top_ref"])


def test_bed_in_air_expands_to_the_steady_column():
    """Table 1's grains in air, Gidaspow, U = 1.5 U_mf (Ergun): the steady column by 0.3 s."""
    r = layers.bed(Ly=8e-4, t_end=0.3, n_times=3, path=layers.BED_AIR)
    assert r["U"] > 1.4 * r["U_mf"]
    assert r["errors"][-1] < 0.02, r["errors"]
    assert abs(r["tops"][-1] - r["top_ref"]) < 2 * 2.5e-4, (r["tops"], r["top_ref"])
