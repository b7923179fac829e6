"""The time loop over one slab: :class:`parsph.simulation.solver.Simulation` and the run-time checks.

May import: every layer below (physics, sph, parallel, output, setup); never the command line.
"""
