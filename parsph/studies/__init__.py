"""Studies built from runs, and the benchmarks: ``parsph converge`` (its run files, runs, analysis and
report) and the error estimates from them, the stability map, the accuracy sweep, the benchmarks and
scaling measurements, the cases they run and the one resumable runner they share (:mod:`.runs`).

What the scripts in scripts/ compute lives here, so that each script is argument parsing and calls,
none imports another, and a study's code is tested and layered like the rest of the package.

May import: every layer below the command line.
"""
