"""Bad run files and options: exit code 2 and one stderr line naming the key, no traceback.

Every case runs the real CLI (``parsph.cli.main(["run", FILE, "--out", DIR, ...])``, what
``python -m parsph`` calls) with its output captured; all the cases of the module run in one
subprocess (mpi_helpers/cli_batch.py), since a process spends most of its second starting
Python and MPI. The valid override, the positive control, runs as a process of its own.
"""
import json
import re
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import pytest

from parsph.errors import ConfigError
from conftest import PAPER_TOML, ROOT, cli_env, run_cli

BATCH = ROOT / "tests" / "mpi_helpers" / "cli_batch.py"

PAPER = PAPER_TOML.read_text()
SEDIMENTATION = (ROOT / "run" / "sedimentation.toml").read_text()
BED = (ROOT / "run" / "fluidized_bed.toml").read_text()


def no_gas(text):
    """A run file without its [gas] section."""
    out, n = re.subn(r"^\[gas\]\n(?:[^\[\n].*\n|\n)*", "", text, flags=re.M)
    assert n == 1 and "drag =" not in out
    return out



def edit(pattern, repl):
    """The paper run file with one line changed (``pattern`` must match exactly once)."""
    text, n = re.subn(pattern, repl, PAPER, flags=re.M)
    assert n == 1, pattern
    return text


# name: (run-file text or None for the paper file, extra CLI args, strings the message must contain)
CASES = {
    "unknown_key": (edit(r"^Nx = 50$", "Nx = 50\nNz = 3"), [], ["numerics.Nz", "unknown key"]),
    "unknown_section": (PAPER + "\n[bogus]\nx = 1\n", [], ["bogus", "unknown section"]),
    "string_for_number": (edit(r"^L = 0.01 ", 'L = "0.01" '), [], ["domain.L", "number"]),
    "float_for_Nx": (edit(r"^Nx = 50$", "Nx = 50.0"), [], ["numerics.Nx", "integer"]),
    "bool_for_number": (edit(r"^rho_s = 2000.0 ", "rho_s = true "), [], ["material.rho_s", "number"]),
    "L_zero": (edit(r"^L = 0.01 ", "L = 0 "), [], ["domain.L", "positive"]),
    "L_negative": (edit(r"^L = 0.01 ", "L = -1 "), [], ["domain.L", "positive"]),
    "h_zero": (edit(r"^h = 2.5e-4 ", "h = 0.0 "), [], ["numerics.h", "positive"]),
    "Ly_negative": (edit(r"^Ly = 0.01 ", "Ly = -0.01 "), [], ["domain.Ly", "positive"]),
    "layers_short": (edit(r"^V_w = 1.0 ", "layers = 1\nV_w = 1.0 "), [], ["walls.layers", "support"]),
    "dt_unstable": (edit(r"^dt = 1.0e-5 ", "dt = 2e-4 "), [],
                    ["numerics.dt", "stability limit", "(viscous)"]),
    "missing_required": (edit(r"^k = 1.0 .*$", ""), [], ["material.k", "missing"]),
    "invalid_toml": (edit(r"^L = 0.01 ", "L = = 0.01 "), [], ["bad.toml", "TOML"]),
    "theta0_one": (edit(r"^theta0 = 0.35$", "theta0 = 1.0"), [], ["material.theta0"]),
    "theta0_above_one": (edit(r"^theta0 = 0.35$", "theta0 = 1.5"), [], ["material.theta0"]),
    "theta0_string": (edit(r"^theta0 = 0.35$", 'theta0 = "dense"'), [], ["material.theta0"]),
    "kernel_unknown": (edit(r'^kernel = "cubic_spline"$', 'kernel = "gaussian"'), [],
                       ["numerics.kernel", "cubic_spline"]),
    "h_and_h_over_dx": (edit(r"^h = 2.5e-4 ", "h_over_dx = 1.25\nh = 2.5e-4 "), [], ["numerics.h"]),
    "times_after_end": (edit(r"^t_end = 0.5$", "t_end = 0.05"), [], ["output.times"]),
    "set_unknown_key": (None, ["--set", "numerics.foo=1"], ["numerics.foo", "unknown key"]),
    "set_unknown_section": (None, ["--set", "nosuch.x=1"], ["nosuch"]),
    "set_bad_type": (None, ["--set", "numerics.Nx=fifty"], ["numerics.Nx", "integer"]),
    "set_no_equals": (None, ["--set", "numerics.Nx"], ["numerics.Nx"]),
    "nonexistent_file": ("MISSING", [], ["no_such_run.toml", "cannot read"]),
    "existing_output": ("EXISTING", [], ["couette_paper_0000.h5", "exists", "--force"]),
    # the check interval is [checks] every; output.check_every is no key of the run file
    "old_check_every": (None, ["--set", "output.check_every=5"], ["output.check_every", "unknown key"]),
    "checks_every_zero": (None, ["--set", "checks.every=0"], ["checks.every", "at least 1"]),
    "checks_theta_change_negative": (None, ["--set", "checks.theta_change=-0.1"],
                                     ["checks.theta_change", "positive"]),
    "checks_energy_not_bool": (None, ["--set", "checks.energy=1"], ["checks.energy", "true or false"]),
    "integrator_unknown": (None, ["--set", "numerics.integrator=rk4"], ["numerics.integrator", "midpoint"]),
    "viscosity_form_unknown": (None, ["--set", "numerics.viscosity_form=mean"],
                               ["numerics.viscosity_form", "symmetric"]),
    "dt_string": (None, ["--set", "numerics.dt=fast"], ["numerics.dt", "number"]),
    "pressure_form_unknown": (None, ["--set", "numerics.pressure_form=exact"],
                              ["numerics.pressure_form", "consistent"]),
    # 2h = 0.02 m is wider than both L and L_y: h is the cause, not domain.Ly
    "h_too_large": (None, ["--set", "numerics.h=0.01"], ["error: numerics.h:", "too large", "2h = 0.02 m"]),
    # the support does not reach the next particle: h / dx is the cause, not the wall layers
    "h_over_dx_too_small": (edit(r"^h = 2.5e-4 .*$", "h_over_dx = 0.3"), [],
                            ["error: numerics.h_over_dx:", "too small", "h / dx > 0.5"]),
    # [gas] (docs/physics.md, "The solid phase in a gas")
    "gas_drag_unknown": (None, ["--set", "gas.drag=ergun"], ["gas.drag", "wen_yu"]),
    "gas_mu_zero": (None, ["--set", "gas.drag=stokes", "--set", "gas.mu=0.0"], ["gas.mu", "positive"]),
    "gas_denser_than_solids": (None, ["--set", "gas.drag=stokes", "--set", "gas.rho=2500.0"],
                               ["gas.rho", "not below", "rho_s"]),
    "gas_velocity_length": (None, ["--set", "gas.drag=stokes", "--set", "gas.velocity=[1.0]"],
                            ["gas.velocity", "needs 2 components"]),
    "gas_column_without_gravity": (None, ["--set", "gas.drag=stokes", "--set", "gas.flow=column"],
                                   ["body_force.g", "needs gravity"]),
    "gas_column_tilted_gravity": (None, ["--set", "gas.drag=stokes", "--set", "gas.flow=column",
                                         "--set", "body_force.g=[-9.81, 1.0]"], ["body_force.g", "one axis"]),
    "gas_U_for_stream": (None, ["--set", "gas.drag=stokes", "--set", "gas.U=0.1"], ["gas.U", "column"]),
    "gas_velocity_for_column": (None, ["--set", "gas.drag=stokes", "--set", "gas.flow=column",
                                       "--set", "body_force.g=[-9.81, 0.0]", "--set", "gas.velocity=[0.0, 1.0]"],
                                ["gas.velocity", "column"]),
    "gas_key_without_drag": (None, ["--set", "gas.rho=1.2"], ["gas.rho", "no effect", "gas.drag"]),
    "gas_U_negative": (None, ["--set", "gas.drag=stokes", "--set", "gas.flow=column",
                              "--set", "body_force.g=[-9.81, 0.0]", "--set", "gas.U=-0.1"], ["gas.U", "negative"]),
    "grain_diameter_zero": (None, ["--set", "material.d=0.0"], ["material.d", "positive"]),
    "drag_update_unknown": (None, ["--set", "numerics.drag_update=exact"], ["numerics.drag_update", "implicit"]),
    "gas_explicit_dt_unstable": (None, ["--set", "gas.drag=stokes", "--set", "gas.rho=1000.0",
                                        "--set", "gas.mu=1e-3", "--set", "material.d=1e-5",
                                        "--set", "numerics.drag_update=explicit"],
                                 ["numerics.dt", "stability limit", "(drag)"]),
    # the layer scenes (sedimentation, fluidized_bed): what their check() refuses, and scene.height elsewhere
    "layer_gravity_up": (SEDIMENTATION, ["--set", "body_force.g=[9.81, 0.0]"], ["body_force.g", "along -x"]),
    "layer_gravity_along_y": (no_gas(SEDIMENTATION), ["--set", "body_force.g=[0.0, -9.81]"],
                              ["body_force.g", "along -x"]),
    "sedimentation_fed": (SEDIMENTATION, ["--set", "gas.U=0.01"], ["gas.U", "closed column", "fluidized_bed"]),
    "sedimentation_stream": (SEDIMENTATION, ["--set", "gas.flow=stream"], ["gas.flow", '"column"']),
    "bed_without_gas": (no_gas(BED), [], ["gas.U", "needs a gas column fed at U > 0"]),
    "bed_U_zero": (BED, ["--set", "gas.U=0.0"], ["gas.U", "U > 0"]),
    "layer_height_at_lid": (SEDIMENTATION, ["--set", "scene.height=0.0296"],
                            ["scene.height", "less than 2h", "domain.L = 0.03 m"]),
    "bed_expands_to_lid": (BED, ["--set", "gas.U=0.03"], ["domain.L", "expanded bed reaches 0.0449 m"]),
    "bed_too_tall_to_expand": (BED, ["--set", "scene.height=0.0199"], ["domain.L", "expanded bed reaches"]),
    "height_for_couette": (None, ["--set", "scene.height=0.005"], ["scene.height", "the couette scene has none"]),
}


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    base = tmp_path_factory.mktemp("bad_runs")
    jobs = {}
    for name, (text, extra, _) in CASES.items():
        out = base / f"out_{name}"
        if text is None:
            path = PAPER_TOML
        elif text == "MISSING":
            path = base / "no_such_run.toml"
        elif text == "EXISTING":
            path = PAPER_TOML
            out.mkdir()
            (out / "couette_paper_0000.h5").write_bytes(b"")  # an earlier run's first output
        else:
            path = base / name / "bad.toml"
            path.parent.mkdir()
            path.write_text(text)
        jobs[name] = ["run", str(path), "--out", str(out), "--quiet", *extra]
    # the positive control: a valid override runs (10 steps) and writes its output
    ok_out = base / "ok"
    jobs["valid_override"] = ["run", str(PAPER_TOML), "--out", str(ok_out), "--quiet",
                              "--set", "output.t_end=1e-4", "--set", "output.times=[1e-4]"]
    valid = jobs.pop("valid_override")
    with ThreadPoolExecutor(max_workers=2) as pool:
        ok = pool.submit(run_cli, *valid, timeout=120)
        batch = subprocess.run([sys.executable, str(BATCH)], input=json.dumps(jobs), cwd=ROOT, env=cli_env(),
                               capture_output=True, text=True, timeout=300)
        assert batch.returncode == 0, batch.stderr
        res = {name: tuple(r) for name, r in json.loads(batch.stdout).items()}
        res["valid_override"] = ok.result()
    res["_ok_out"] = ok_out
    res["_existing"] = base / "out_existing_output" / "couette_paper_0000.h5"
    return res


@pytest.mark.parametrize("name", list(CASES))
def test_bad_input(results, name):
    rc, out, err = results[name]
    assert rc == 2, (rc, out, err)
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("parsph: error: ")
    for s in CASES[name][2]:
        assert s in lines[0], (s, lines[0])
    assert out.strip() == ""  # nothing announced for a run that does not start


def test_existing_output_left_alone(results):
    """The refused run did not touch the existing output."""
    rc, _, _ = results["existing_output"]
    assert rc == 2
    f = results["_existing"]
    assert f.is_file() and f.stat().st_size == 0


def test_valid_override_runs(results):
    rc, out, err = results["valid_override"]
    assert rc == 0, err
    assert "Traceback" not in err
    assert "10 steps" in out
    # one file per output time: the single output (t = 1e-4 s) is output 0000, complete (renamed)
    files = sorted(p.name for p in results["_ok_out"].iterdir())
    assert files == ["couette_paper.cells.h5", "couette_paper.xdmf", "couette_paper_0000.h5"], files


def test_set_overrides_change_config(paper_cfg):
    base = paper_cfg()
    cfg = paper_cfg("numerics.Nx=20", "numerics.h=6.25e-4", "material.k=0.5",
                    "numerics.kernel=wendland_c2", "output.times=[0.01, 0.02]")
    assert (base.Nx, cfg.Nx) == (50, 20)
    assert cfg.dx == pytest.approx(5e-4, rel=1e-12)
    assert cfg.h == pytest.approx(6.25e-4, rel=1e-12)
    assert cfg.layers == 3  # ceil(2h / dx) = ceil(2.5)
    assert cfg.nu == pytest.approx(0.5 * 0.35 / 2000.0, rel=1e-12)
    assert cfg.kernel == "wendland_c2"
    assert cfg.output_times == (0.01, 0.02)
    assert tuple(round(t / cfg.dt) for t in cfg.output_times) == (1000, 2000)  # output steps
    assert cfg.mass == pytest.approx(2000.0 * 0.35 * 5e-4 ** 2, rel=1e-12)
    # the stored run file carries the overrides
    assert "Nx = 20" in cfg.text and "k = 0.5" in cfg.text
    # and the original is untouched by a later load
    assert paper_cfg().Nx == 50


def test_config_error_names_key(paper_cfg):
    with pytest.raises(ConfigError) as e:
        paper_cfg("numerics.dt=2e-4")   # above the viscous limit 2 / gamma_max = 1.14e-4 s (docs/stability.md)
    assert e.value.key == "numerics.dt"
    with pytest.raises(ConfigError) as e:
        paper_cfg("walls.layers=2")  # 2 dx = 4e-4 m < 2h = 5e-4 m
    assert e.value.key == "walls.layers"
    # allow_unstable_dt lets the same dt through
    cfg = paper_cfg("numerics.dt=2e-4", "numerics.allow_unstable_dt=true")
    assert cfg.dt == 2e-4


def test_checks_section(paper_cfg):
    """Run-time checks live in [checks] (defaults: every 20 steps, theta within 50%, energy bound on)."""
    cfg = paper_cfg()
    assert cfg.get("checks.every") == 20
    assert cfg.get("checks.theta_change") == 0.5
    assert cfg.get("checks.energy") is True
    cfg = paper_cfg("checks.every=5", "checks.theta_change=0.2", "checks.energy=false")
    assert (cfg.get("checks.every"), cfg.get("checks.theta_change"), cfg.get("checks.energy")) == (5, 0.2, False)
    assert "[checks]" in cfg.text and "every = 5" in cfg.text
    with pytest.raises(ConfigError) as e:
        paper_cfg("output.check_every=5")
    assert e.value.key == "output.check_every"


def test_numerics_options(paper_cfg):
    """integrator, viscosity_form and dt = "auto" are validated and stored."""
    base = paper_cfg()
    assert base.integrator == "paper" and base.get("numerics.viscosity_form") == "paper"
    assert base.get("numerics.pressure_form") == "paper"
    assert not base.dt_auto
    cfg = paper_cfg("numerics.integrator=midpoint", "numerics.viscosity_form=symmetric",
                    'numerics.dt="auto"', "numerics.dt_safety=0.5")
    assert cfg.integrator == "midpoint" and cfg.get("numerics.viscosity_form") == "symmetric"
    assert cfg.dt_auto
    assert cfg.dt == pytest.approx(0.5 * min(cfg.limits.values()), rel=1e-12)


@pytest.mark.parametrize("overrides, key, words", [
    (["numerics.h=0.01"], "numerics.h", ["too large", "wider than the channel (L = 0.01 m)"]),
    (["numerics.h=None", "numerics.h_over_dx=60"], "numerics.h_over_dx", ["h / dx = 60", "too large"]),
    (["numerics.h=1e-6"], "numerics.h", ["h / dx = 0.005 is too small", "need h / dx > 0.5"]),
    (["numerics.h=None", "numerics.h_over_dx=1e-9"], "numerics.h_over_dx", ["too small"]),
    (["numerics.h=None", "numerics.h_over_dx=0.5"], "numerics.h_over_dx", ["too small"]),   # 2h = dx exactly
    (["numerics.h=None", "numerics.h_over_dx=0.3", "walls.layers=1"], "numerics.h_over_dx", ["too small"]),
    (["domain.Ly=0.0004"], "domain.Ly", ["shorter than the kernel support 2h = 0.0005 m"]),  # Ly is the cause
], ids=["h_large", "ratio_large", "h_small", "ratio_tiny", "ratio_half", "ratio_small_layers", "Ly_short"])
def test_smoothing_length_errors_name_the_cause(overrides, key, words):
    """An h too large for the box or too small to reach a neighbour is blamed on the h key given."""
    from parsph.setup import config
    from parsph.setup.runfile import RunFile
    from conftest import paper_raw
    raw = paper_raw()
    if "numerics.h=None" in overrides:
        raw["numerics"].pop("h")
    run_file = RunFile(raw).override([o for o in overrides if o != "numerics.h=None"])
    with pytest.raises(ConfigError) as e:
        config.build(run_file)
    assert e.value.key == key, e.value
    for w in words:
        assert w in str(e.value), (w, str(e.value))
    assert "at least 0" not in str(e.value)
