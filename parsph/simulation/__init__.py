"""The time loop over one slab (:class:`parsph.simulation.solver.Simulation`), the run-time checks, and one
case from a validated run to its output files (:func:`parsph.simulation.case.run_case`).

May import: every layer below (physics, sph, parallel, output, setup); never the command line.
"""
