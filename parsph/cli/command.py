"""The ``parsph`` command: run, check, converge, plot.

    parsph run CONFIG [--set section.key=value ...] [--out DIR] [--force] [--restart OUTPUT] [--quiet]
    parsph check OUTPUT [--tol TOL]
    parsph converge CONFIG [--levels 3] [--ratio 2] [--target ERR] [--out DIR] [--family NAME ...] [--dt-scaling dx2|limit]
    parsph plot OUTPUT [--png FILE] [--particles [--field vy|vx|theta] [--times T ...]]
                       [--grid [--field theta|p] [--times T ...] [--animate FILE.gif]]
                       [--field F] [--times T ...] [--animate FILE.gif]   (the grid's where there is one)

The commands live in :mod:`parsph.cli.run` (run), :mod:`parsph.cli.converge`
(converge) and :mod:`parsph.cli.report` (check, plot); the exit codes in
:mod:`parsph.cli.exits`.

Exit codes: 0 success; 1 ``check`` above tolerance or an unexpected error;
2 bad input (run file, options, output path); 3 a run-time check failed, or the gas solve
(after writing the state it failed on as a restart point); 130 / 143 stopped by SIGINT / SIGTERM
after writing a restart point.
"""
import argparse
import sys

from parsph import __version__
from parsph.errors import UsageError
from .converge import cmd_converge
from .exits import EXIT_BAD_INPUT
from .report import cmd_check, cmd_plot
from .run import cmd_run


DESCRIPTION = ("parsph: parallel SPH for the solid phase of granular two-fluid models. Four commands: "
               "run, check, converge, plot; 'parsph COMMAND --help' for the options of one.")


def build_parser():
    p = argparse.ArgumentParser(prog="parsph", description=DESCRIPTION)
    p.add_argument("--version", action="version", version=f"parsph {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    r = sub.add_parser("run", help="run a case (under mpirun for several ranks)")
    r.add_argument("config", help="run file (TOML)")
    r.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE", help="override a run-file key")
    r.add_argument("--out", help="output directory (default out/<run-file name>; with --restart, the restart's)")
    r.add_argument("--force", action="store_true", help="overwrite existing output files")
    r.add_argument("--restart", metavar="OUTPUT",
                   help="continue from the last snapshot of OUTPUT (a directory or one output file)")
    r.add_argument("--quiet", action="store_true", help="no progress lines")
    r.add_argument("--threads", type=int, default=1, metavar="N",
                   help="threads per rank in the particle loops (default 1: one rank per core; "
                        "ranks x threads should not exceed the cores)")
    c = sub.add_parser("check", help="print the error table of a run; exit 1 above --tol")
    c.add_argument("output", help="output directory or file")
    c.add_argument("--tol", type=float, default=None,
                   help="the largest error accepted: of the error table's max error (relative to the scene's "
                        "scale; default 0.02); for a layer scene (sedimentation, fluidized_bed), of both its "
                        "measures: the heights of 5-95%% of the mass against the transient's, relative to H0 "
                        "(default 0.03), and the interior theta against the end state's, relative (default 0.02)")
    cv = sub.add_parser("converge", help="run at several resolutions; estimated error and cost of each "
                                         "(under mpirun for several ranks)")
    cv.add_argument("config", help="run file (TOML): the coarsest level")
    cv.add_argument("--levels", type=int, default=3, help="resolutions N_x, R N_x, R^2 N_x, ... (default 3)")
    cv.add_argument("--ratio", type=int, default=2, help="refinement ratio R (default 2)")
    cv.add_argument("--target", type=float, metavar="ERR",
                    help="predict the cheapest N_x (and --family) with max error <= ERR at every output time")
    cv.add_argument("--out", help="directory of the levels and of converge.json / converge.png "
                                  "(default out/<run-file name>_converge)")
    cv.add_argument("--family", action="append", metavar="NAME",
                    help="numerics to study: given (the run file's; default), fast, accurate, paper "
                         "(the presets'); repeat to compare")
    cv.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE", help="override a run-file key")
    cv.add_argument("--force", action="store_true", help="overwrite a level's outputs that cannot be reused")
    cv.add_argument("--threads", type=int, default=1, metavar="N", help="threads per rank (as for run)")
    cv.add_argument("--dt-scaling", choices=("limit", "dx2"), default="dx2",
                    help="dx2 (default): dt ~ dx^2 from the coarsest level's limit, so the time error falls as "
                         "dx^2 at every level; limit: each level at its own stability limit (cheaper; mixed orders)")
    pl = sub.add_parser("plot", help="PNG of the simulated profiles over the reference; with --particles, "
                                     "one PNG of the particles per output time")
    pl.add_argument("output", help="output directory or file")
    pl.add_argument("--png", help="PNG path of the profiles (default next to the outputs)")
    pl.add_argument("--particles", action="store_true",
                    help="instead: the particles of each output with particles, coloured by --field, walls marked "
                         "(3-D: the middle z-layer), as DIR/<name>_<field>_NNNN.png")
    pl.add_argument("--grid", action="store_true",
                    help="instead: the solved gas's grid of each output that holds one (theta or p', upright, mm), "
                         "as DIR/<name>_grid_<field>_NNNN.png")
    pl.add_argument("--animate", metavar="FILE",
                    help="the grid's pictures (--grid implied) and an animation over the outputs (.gif, or .mp4 "
                         "where ffmpeg is there)")
    pl.add_argument("--field", choices=("vy", "vx", "theta", "p"), default=None,
                    help="colour of --particles (vy, vx, theta; default vy) or --grid (theta, p; default theta); "
                         "alone, the grid's pictures where the outputs hold one, else the particles'")
    pl.add_argument("--times", type=float, nargs="+", metavar="T",
                    help="the pictures only at these output times [s] (default: every output that has what they "
                         "draw); alone, as --field alone")
    return p


def main(argv=None):
    args = build_parser().parse_args(argv)
    try:
        return {"run": cmd_run, "converge": cmd_converge, "check": cmd_check, "plot": cmd_plot}[args.command](args)
    except UsageError as e:
        print(f"parsph: error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
