"""One evaluation of the rates on the Python path: the stages of :mod:`.stages` in their order, as the
compiled block takes them, with the ghosts' rho sent through mpi4py where compiled code cannot call MPI
(``HALO``) and the solved gas's stage where the scene has it (``GAS``).

Used by the driver for a state's first rates and after a block returned mid-step, and by the Python path
(:meth:`parsph.simulation.solver.Simulation.python_step`), the route on an MPI whose handles the bindings do
not know and the compiled route's test oracle.
"""
import numpy as np

from parsph.parallel import native_mpi
from parsph.sph import dispatch, pass_data
from . import stages

FUNCTIONS = {"density": stages.density, "after_density": stages.after_density}


class Evaluation:
    """Evaluates rho, theta and the accelerations of the owned particles from the passes' data of ``rates``
    (:class:`parsph.sph.rates.Rates`: the list, its scratch, the run's numbers and terms)."""

    def __init__(self, rates, ring, clock, gas=None):
        """``ring``: the slab ring (its plan, and its mpi4py rounds where the plan holds no MPI handles);
        ``clock``: the seconds of Eq. (3) and of an mpi4py round (the other stages count MPI_Wtime's);
        ``gas(ps)``: the solved gas's stage between Eq. (3) and Eq. (5) (None: no solved gas)."""
        why = native_mpi.load()  # the stages' clock, MPI_Wtime, on any MPI
        if why:
            raise RuntimeError(f"the compiled stages need MPI_Wtime from libmpi: {why}")
        self.rates, self.ring, self.clock, self.gas = rates, ring, clock, gas
        self.timers = np.zeros(len(stages.TIMER_PHASES))
        self._calls = dispatch.Calls(FUNCTIONS)

    def forget(self):
        """A list was built: the stages' versions are looked up again for its arrays."""
        self._calls.forget()

    def __call__(self, ps, timers):
        """Fill ps.rho, ps.theta and ps.acc of the owned particles; the stages' seconds into ``timers`` (a
        dict of the solver's phases; the gas stage counts its own)."""
        R, run = self.rates, self._calls
        threaded = dispatch.threaded()
        gather = R.gather_for(threaded)
        lst, parts, c, sw = R.list, pass_data.particle_arrays(ps), R.consts, R.switches
        thr, t = pass_data.switch(threaded), self.timers
        t[:] = 0.0
        plan = self.ring.plan(ps.dim)
        t0 = self.clock()
        run("density", lst, parts, c, sw, gather, thr)
        timers["density"] += self.clock() - t0
        code = run("after_density", plan, lst, parts, c, sw, gather, thr, sw.mirror, self.gas is not None,
                   np.int64(stages.START), t)
        if code == stages.HALO:
            t1 = self.clock()
            self.ring.refresh(ps, ps.rho)
            timers["halo"] += self.clock() - t1
            code = run("after_density", plan, lst, parts, c, sw, gather, thr, sw.mirror, self.gas is not None,
                       np.int64(stages.AFTER_HALO), t)
        if code == stages.GAS:
            self.gas(ps)
            code = run("after_density", plan, lst, parts, c, sw, gather, thr, sw.mirror, True,
                       np.int64(stages.FORCES_ONLY), t)
        if code != stages.DONE:
            raise RuntimeError("an MPI call of the compiled evaluation failed")
        timers["density"] += float(t[stages.DENSITY])
        timers["halo"] += float(t[stages.HALO_T])
        timers["forces"] += float(t[stages.FORCES])
