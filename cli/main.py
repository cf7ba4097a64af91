"""`flashbrdf`: the parser assembled from the commands' own subparsers, and errors mapped to exit
status.

Exit status (contract): 0 success, 2 bad input (one line on stderr naming the file or field),
1 anything else; 130 on Ctrl-C and 143 on SIGTERM (no output is left behind: files.outputs).
"""

import importlib
import sys

from flashbrdf.cli.options import OneLineParser

# Each module builds its subparsers (add_parsers) and sets a handler on them; the order here is
# the order of `flashbrdf --help`.
COMMAND_MODULES = ("cmd_brdf", "cmd_train", "cmd_infer", "cmd_extract", "cmd_segment",
                   "cmd_render", "cmd_run", "cmd_batch", "cmd_evaluate", "cmd_export",
                   "cmd_import")


def build_parser():
    from flashbrdf import __version__
    parser = OneLineParser(prog="flashbrdf",
                           description="Flash photograph + known geometry -> full measured BRDF "
                                       "(Georgoulis et al., ICCV 2015).")
    parser.add_argument("--version", action="version", version=f"flashbrdf {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMAND_MODULES:
        importlib.import_module(f"flashbrdf.cli.{name}").add_parsers(sub)
    return parser


def main(argv=None):
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as done:  # -h, --version (0) or a bad option (2, its one line printed)
        return done.code
    # files.* import nothing heavy: they cost `--help` nothing, and are needed for every command
    from flashbrdf.files.errors import InputError
    from flashbrdf.files.signals import Terminated, handle_signals, hold_native_stderr
    try:
        with hold_native_stderr(), handle_signals():
            return args.handler(args) or 0
    except InputError as err:
        print(f"flashbrdf {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # staged outputs were removed on the way out
        print(f"flashbrdf {args.command}: interrupted; {_left(args.command)}", file=sys.stderr)
        return 130
    except Terminated:
        print(f"flashbrdf {args.command}: terminated; {_left(args.command)}", file=sys.stderr)
        return 143


def _left(command):
    """What an interrupted command leaves: batch keeps the captures it finished (a rerun resumes
    there); every other command builds its output aside and leaves none."""
    return ("the captures already finished are kept, and a rerun resumes; no summary written"
            if command == "batch" else "no output written")


if __name__ == "__main__":
    sys.exit(main())
