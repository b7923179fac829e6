"""The integrator of the Python path (LAMMPS's Fix for the time integration): the paper's step,
Eqs. (6)-(7), or the midpoint scheme's two halves (:mod:`parsph.sph.integrators`), with the gas's drag
explicit or implicit in v. The compiled blocks take the same functions through :attr:`Integrator.modes`."""
import numpy as np

from parsph.sph import dispatch, integrators, pass_data, walls


class Integrator:
    """``numerics.integrator`` over the owned particles; adds the midpoint scheme's saved state to ``ps``."""

    def __init__(self, cfg, ps):
        self.h = float(cfg.h)
        self.midpoint = cfg.integrator == "midpoint"
        self._midpoint = pass_data.switch(self.midpoint)
        self.position_fields = ("pos",)  # the fields a build wraps into the box
        if self.midpoint:
            ps.add_field("pos0")
            ps.add_field("vel0")
            self.position_fields = ("pos", "pos0")
        gas = cfg.gas
        self.drag = gas is not None
        self.implicit = pass_data.switch(gas is not None and gas.implicit)
        self.explicit_drag = gas is not None and not gas.implicit  # the auto rule's drag limit applies
        self.no_state = np.zeros((0, cfg.dim))
        # walls.reflect's plates beside the mirror: L, and the side walls' Ly (0: none) in the period along y
        self.plates = (float(cfg.L), float(cfg.Ly) if cfg.sides else 0.0, float(cfg.Ly_ring)) \
            if cfg.scene.free_surface else None
        self.reflected = 0  # grains walls.reflect put back on a plate (this rank, the Python path)

    def drag_field(self, ps):
        """The particles' drag coefficients as the integrators take them (an empty array without a gas; read
        anew each step, as the field is reallocated when the particles grow)."""
        return ps.drag_coef if self.drag else self.no_state

    def first(self, ps, dt):
        """The paper's whole step, or the midpoint scheme's first half; returns the count of bad particles.
        The functions :func:`integrators.steps_for` chooses for this process's thread mode, as the compiled
        block's calls resolve to: on one thread the serial loops."""
        pos0, vel0 = (ps.pos0, ps.vel0) if self.midpoint else (self.no_state, self.no_state)
        bad = integrators.integrate_first(self._threaded(), self._midpoint, ps.pos, ps.vel, ps.acc, ps.kind, ps.n_own,
                                          dt, pos0, vel0, ps.jump, self.h, self.drag_field(ps), self.implicit)
        self._reflect(ps)
        return bad

    def _reflect(self, ps):
        if self.plates is not None:
            self.reflected += walls.reflect(ps.pos, ps.vel, ps.kind, ps.n_own, *self.plates)

    def second(self, ps, dt):
        """The midpoint scheme's second half, from the rates at the midpoint."""
        bad = integrators.integrate_second(self._threaded(), ps.pos, ps.vel, ps.acc, ps.kind, ps.n_own, dt, ps.pos0,
                                           ps.vel0, ps.jump, self.h, self.drag_field(ps), self.implicit)
        self._reflect(ps)
        return bad

    @staticmethod
    def _threaded():
        return pass_data.switch(dispatch.threaded())

    def motion(self, ps):
        """The particle state the compiled block integrates besides ParticleArrays (block.Motion's fields)."""
        mid = self.midpoint
        return ps.disp, ps.ref, ps.jump, ps.pos0 if mid else self.no_state, ps.vel0 if mid else self.no_state
