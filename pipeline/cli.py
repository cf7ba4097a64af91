"""The `flashbrdf` command line: argument parsing and error-to-exit-status mapping.

Exit status (contract): 0 success, 2 bad input (one line on stderr naming the file or field),
1 anything else; 130 on Ctrl-C and 143 on SIGTERM (no output is left behind, see safety.py). Each sub-command lives in pipeline/commands.py.
"""

import argparse
import sys

from flashbrdf.brdf.errors import InputError
from flashbrdf.pipeline import commands
from flashbrdf.pipeline.cmd_colmap import add_import_colmap_parser
from flashbrdf.pipeline.dask_engine import add_engine_options
from flashbrdf.pipeline.safety import Terminated, handle_signals, hold_native_stderr

FORCE_HELP = "replace OUT_DIR if an earlier flashbrdf command made it (never any other folder)"


class _OneLineParser(argparse.ArgumentParser):
    """argparse, but a bad option gives the contract's one stderr line (exit 2), not the usage
    block first; `-h` still prints the usage. Sub-parsers inherit the class."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} -h)\n")

    def add_argument(self, *args, **kwargs):
        """Every text argument (a path, a list, a name) must be non-empty: `--slice ""` would
        otherwise read as the current folder, or as the option not given."""
        if kwargs.get("action", "store") in ("store", "append") and "type" not in kwargs \
                and "choices" not in kwargs:
            kwargs["type"] = _nonempty
        return super().add_argument(*args, **kwargs)


def _nonempty(text):
    if not text:
        raise argparse.ArgumentTypeError("is empty")
    return text


def _parser():
    p = _OneLineParser(
        prog="flashbrdf",
        description="Flash photograph + known geometry -> full measured BRDF "
                    "(Georgoulis et al., ICCV 2015).")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    s = sub.add_parser("merl-slice", help="write the theta_d = 0 slice of a MERL table")
    s.add_argument("brdf", metavar="BRDF.binary")
    s.add_argument("--out", required=True, metavar="SLICE.csv")

    s = sub.add_parser("train", help="train a DS-GPLVM model on MERL tables")
    s.add_argument("--merl-dir", required=True, action="append", metavar="DIR",
                   help="a folder of MERL tables; repeat it to train on the tables of several")
    s.add_argument("--out", required=True, metavar="MODEL.npz")
    s.add_argument("--views", default="1d,2d", choices=["1d,2d", "1d,2d,3d"])
    s.add_argument("--feature-space", default="auto", choices=["auto", "lab", "rgb"],
                   help="dsgplvm features: CIELAB (the paper) or RGB of ln(1 + rho/1e-3); auto "
                        "picks one on a held-out 20%% of the tables, with slice anchoring")
    s.add_argument("--seed", type=int, default=0)

    s = sub.add_parser("infer", help="infer a full BRDF from a slice")
    s.add_argument("--model", metavar="MODEL.npz")
    s.add_argument("--slice", required=True, metavar="SLICE.csv")
    s.add_argument("--out", required=True, metavar="BRDF.binary")
    s.add_argument("--method", default="dsgplvm",
                   choices=["dsgplvm", "pca", "noll", "chandraker", "ashikhmin"])
    s.add_argument("--merl-dir", action="append", metavar="DIR",
                   help="the model's training tables, for 3D (repeat it for a model trained on "
                        "several folders)")
    s.add_argument("--no-anchor", action="store_true",
                   help="dsgplvm: keep the paper's prediction as is; by default it is corrected along "
                        "theta_h to pass through the observed slice, carried over theta_d, and "
                        "blended toward the observed row near theta_d = 0, and half of its weights "
                        "over the training tables come from a direct fit to the slice")
    s.add_argument("--view", default="auto", choices=["auto", "2d", "3d"],
                   help="predict 2D (copied across phi_d) or 3D; auto: 3D when training tables "
                        "are at hand")

    s = sub.add_parser("extract", help="extract the flash slice from a capture folder")
    s.add_argument("scene_dir", metavar="SCENE_DIR")
    s.add_argument("--out", required=True, metavar="SLICE.csv|DIR")
    s.add_argument("--labels", metavar="LABELS.png",
                   help="one slice per material: DIR/material_<k>.csv and DIR/coverage.json")
    s.add_argument("--max-theta-d", type=float, metavar="DEG",
                   help="reject pixels with theta_d above this (default 5 degrees)")
    s.add_argument("--min-cos", type=float, help="reject cos(theta_i|o) below this (default 0.1)")
    s.add_argument("--silhouette-px", type=int, metavar="PX",
                   help="reject pixels this close to the object's outline (default 1)")
    s.add_argument("--force", action="store_true", help="with --labels: " + FORCE_HELP)

    s = sub.add_parser("segment", help="label the flash photo's pixels by material")
    s.add_argument("scene_dir", metavar="SCENE_DIR")
    s.add_argument("--out", required=True, metavar="LABELS.png")
    s.add_argument("--materials", default="auto", metavar="auto|K")
    s.add_argument("--albedo", metavar="ALBEDO.exr",
                   help="also write a per-pixel diffuse albedo map (textured materials)")

    s = sub.add_parser("render", help="render every reference photo's lighting")
    s.add_argument("scene_dir", metavar="SCENE_DIR")
    s.add_argument("--brdf", required=True, metavar="BRDF.binary[,BRDF2.binary,...]")
    s.add_argument("--labels", metavar="LABELS.png",
                   help="material k of the label image is rendered with the k-th table")
    s.add_argument("--albedo", metavar="ALBEDO.exr",
                   help="a per-pixel diffuse albedo map (segment --albedo) replaces each "
                        "material's diffuse floor")
    s.add_argument("--out", required=True, metavar="OUT_DIR")
    s.add_argument("--force", action="store_true", help=FORCE_HELP)
    s.add_argument("--spp", type=int, default=64)
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--interpolate", action="store_true",
                   help="interpolate the BRDF table between bin centres (default: nearest bin)")

    s = sub.add_parser("compare", help="log-CIELAB Delta E between two images")
    s.add_argument("pred", metavar="PRED.exr")
    s.add_argument("ref", metavar="REF.exr")
    s.add_argument("--mask", metavar="MASK.png")
    s.add_argument("--out", required=True, metavar="OUT_DIR")
    s.add_argument("--force", action="store_true", help=FORCE_HELP)

    s = sub.add_parser("run", help="extract, infer, render and compare in one go")
    s.add_argument("scene_dir", metavar="SCENE_DIR")
    s.add_argument("--out", required=True, metavar="OUT_DIR")
    s.add_argument("--force", action="store_true", help=FORCE_HELP)
    _add_run_options(s)

    s = sub.add_parser("batch", help="run every capture in a folder, as Dask tasks")
    s.add_argument("captures_dir", metavar="CAPTURES_DIR")
    s.add_argument("--out", required=True, metavar="OUT_DIR")
    add_engine_options(s, "the captures", "one worker per core")
    s.add_argument("--force", action="store_true",
                   help="rerun captures whose output is already complete")
    _add_run_options(s)

    s = sub.add_parser("evaluate", help="the paper's Table 1 (and Table 2 with --render)")
    s.add_argument("--merl-dir", required=True, action="append", metavar="DIR",
                   help="training tables (repeatable with --test-dir)")
    s.add_argument("--out", required=True, metavar="OUT_DIR")
    s.add_argument("--force", action="store_true", help=FORCE_HELP)
    s.add_argument("--test-dir", metavar="DIR",
                   help="train on every --merl-dir table, score every method on these tables")
    s.add_argument("--render", action="store_true")
    s.add_argument("--envmap", action="append", metavar="FILE",
                   help="with --render: a lat-long map for Table 2 (repeat it for several; "
                        "default two maps made in code, render.envmap.default_envmaps: a sky "
                        "with a sun and a studio)")
    s.add_argument("--quick", action="store_true")
    s.add_argument("--experiments", type=int, help="number of experiments (default 25)")
    s.add_argument("--time-budget", type=float, metavar="SECONDS",
                   help="stop starting experiments when this wall time would be exceeded")
    add_engine_options(s, "the experiments", "one after the other in this process")

    s = sub.add_parser("export", help="a MERL table for Mitsuba 3, Blender and glTF")
    s.add_argument("brdf", metavar="BRDF.binary")
    s.add_argument("--out", required=True, metavar="DIR")
    s.add_argument("--formats", default="mitsuba,principled,gltf",
                   help="comma-separated, some of mitsuba,principled,gltf (default: all three)")
    s.add_argument("--envmap", metavar="FILE",
                   help="a lat-long map: render a sphere with the table and with its Principled "
                        "fit under it, and record their Delta E in principled.json (default: no "
                        "render check)")
    s.add_argument("--force", action="store_true",
                   help="replace OUT_DIR if an earlier flashbrdf command made it")

    s = sub.add_parser("import-diligent", help="turn a DiLiGenT object folder into a scene folder")
    s.add_argument("obj_dir", metavar="OBJ_DIR")
    s.add_argument("--flash", required=True, type=int, metavar="INDEX")
    s.add_argument("--out", required=True, metavar="SCENE_DIR")
    s.add_argument("--force", action="store_true", help=FORCE_HELP)
    add_import_colmap_parser(sub)
    return p


def _add_run_options(s):
    """The options `run` takes, shared by `batch`."""
    s.add_argument("--model", metavar="MODEL.npz")
    s.add_argument("--methods", default="dsgplvm")
    s.add_argument("--spp", type=int, default=64, help="samples per pixel for environment maps")
    s.add_argument("--materials", default="auto", metavar="auto|K",
                   help="segment into materials first (default auto: K chosen, 1 for one material)")
    s.add_argument("--albedo-map", action="store_true",
                   help="estimate a per-pixel diffuse albedo map (OUT_DIR/albedo.exr) and render "
                        "with it (textured materials)")
    s.add_argument("--no-anchor", action="store_true",
                   help="dsgplvm: keep the paper's prediction as is; by default it is corrected along "
                        "theta_h to pass through the observed slice, carried over theta_d, and "
                        "blended toward the observed row near theta_d = 0, and half of its weights "
                        "over the training tables come from a direct fit to the slice")
    s.add_argument("--export", action="store_true",
                   help="also export the default method's BRDF (flashbrdf export) into OUT_DIR/export "
                        "and render its Principled fit beside the tabulated BRDF")


def main(argv=None):
    try:
        args = _parser().parse_args(argv)
    except SystemExit as done:  # -h (0) or a bad option (2, its one line already printed)
        return done.code
    try:
        with hold_native_stderr(), handle_signals():
            return getattr(commands, args.command.replace("-", "_"))(args) or 0
    except InputError as err:
        print(f"flashbrdf {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # staged outputs were removed on the way out
        print(f"flashbrdf {args.command}: interrupted; no output written", file=sys.stderr)
        return 130
    except Terminated:
        print(f"flashbrdf {args.command}: terminated; no output written", file=sys.stderr)
        return 143


if __name__ == "__main__":
    sys.exit(main())
