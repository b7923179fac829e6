"""Studies built from runs: ``parsph converge`` (its run files, runs, analysis and report) and the error
estimates from them, the stability map's measurements, and the cases the studies and benchmarks run.

May import: every layer below the command line.
"""
