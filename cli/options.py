"""What several commands' parsers share: the parser class, --force, run's options (run, batch) and
the Dask engine's (batch, evaluate)."""

import argparse

MODEL_HELP = ("a trained model (flashbrdf train); default: the shipped one, trained on 99 MERL "
              "(NBRDF proxy) tables (red-specular-plastic held out for the sample capture) and "
              "the 22 RGL (NBRDF proxy) ones (sample_data/models/merl100_1d2d.npz)")
FORCE_HELP = "replace OUT_DIR if an earlier flashbrdf command made it (never any other folder)"
ANCHOR_HELP = ("dsgplvm: keep the paper's prediction as is; by default it is corrected along "
               "theta_h to pass through the observed slice, carried over theta_d, and blended "
               "toward the observed row near theta_d = 0, and half of its weights over the "
               "training tables come from a direct fit to the slice")


class OneLineParser(argparse.ArgumentParser):
    """argparse, but a bad option gives the contract's one stderr line (exit 2), not the usage
    block first; `-h` still prints the usage. Sub-parsers inherit the class."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} -h)\n")

    def add_argument(self, *args, **kwargs):
        """Every text argument (a path, a list, a name) must be non-empty: `--slice ""` would
        otherwise read as the current folder, or as the option not given."""
        if kwargs.get("action", "store") in ("store", "append") and "type" not in kwargs \
                and "choices" not in kwargs:
            kwargs["type"] = nonempty
        return super().add_argument(*args, **kwargs)


def nonempty(text):
    if not text:
        raise argparse.ArgumentTypeError("is empty")
    return text


def add_force(parser, help_text=FORCE_HELP):
    parser.add_argument("--force", action="store_true", help=help_text)


def add_run_options(parser):
    """The options `run` takes, shared by `batch`."""
    parser.add_argument("--model", metavar="MODEL.npz", help=MODEL_HELP)
    parser.add_argument("--methods", default="dsgplvm", metavar="M[,M...]",
                        help="comma-separated, each rendered and compared: dsgplvm, pca, noll, "
                             "chandraker, ashikhmin (default dsgplvm)")
    parser.add_argument("--spp", type=int, default=64,
                        help="samples per pixel for environment maps (default 64)")
    parser.add_argument("--materials", default="auto", metavar="auto|K",
                        help="segment into materials first (default auto: K chosen, 1 for one "
                             "material)")
    parser.add_argument("--albedo-map", action="store_true",
                        help="estimate a per-pixel diffuse albedo map (OUT_DIR/albedo.exr) and "
                             "render with it (textured materials)")
    parser.add_argument("--refine-poses", action="store_true",
                        help="refine each flash view's pose against the pooled slice "
                             "before extracting (extract --refine-poses)")
    parser.add_argument("--no-anchor", action="store_true", help=ANCHOR_HELP)
    parser.add_argument("--envmap", metavar="FILE",
                        help="a lat-long map to render the object and a sphere of each material "
                             "under (OUT_DIR/<method>/preview_*); without reference photos they "
                             "are rendered anyway, under a studio map made in code")
    parser.add_argument("--export", action="store_true",
                        help="also export the default method's BRDF (flashbrdf export) into "
                             "OUT_DIR/export and render its Principled fit beside the tabulated "
                             "BRDF")


def run_options(args):
    """run's options as values (pipeline.run.run_capture's keywords)."""
    return {"model": args.model, "methods": args.methods, "spp": args.spp,
            "materials": args.materials, "albedo_map": args.albedo_map,
            "anchor": not args.no_anchor, "export": args.export, "envmap": args.envmap,
            "refine_poses": args.refine_poses}


def add_engine_options(parser, what, default):
    """--workers N and --scheduler ADDRESS; `default` says what happens without either."""
    parser.add_argument("--workers", type=int, metavar="N",
                        help=f"run {what} as tasks on a local Dask cluster of N worker processes "
                             f"(the cores shared out between them); without --workers and "
                             f"--scheduler: {default}")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help=f"run {what} on the running Dask scheduler at ADDRESS "
                             "(tcp://HOST:PORT) instead of a local cluster")
