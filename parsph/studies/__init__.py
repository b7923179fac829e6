"""Studies built from runs: ``parsph converge`` (the levels, their analysis and report) and the error
estimates from them.

May import: every layer below the command line.
"""
