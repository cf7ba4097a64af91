"""Checks of the option values `run`, `batch`, `render` and `segment` share: method names, the
model file, samples per pixel, the number of materials. Each returns the value to use or raises
InputError naming the option."""

from pathlib import Path

from flashbrdf.files.errors import InputError, no_file
from flashbrdf.files.outputs import files_fingerprint

# The model `run` and `batch` use when none is given; beside the package (sample_data/ in the
# repository, flashbrdf/sample_data/ in a wheel).
DEFAULT_MODEL = Path(__file__).resolve().parents[1] / "sample_data" / "models" / "merl100_1d2d.npz"
METHODS_NEEDING_NO_MODEL = ("chandraker",)
MAX_SPP = 1 << 20  # samples per pixel; 16,384 times the default


def split_names(methods):
    """--methods "a,b" (or a list) as the list of names given, unchecked."""
    text = methods if isinstance(methods, str) else ",".join(methods)
    return [m.strip() for m in text.split(",") if m.strip()]


def method_names(methods):
    """--methods "a,b" (or a list) as a list of distinct method names, in order; InputError for
    an unknown name or none."""
    from flashbrdf.infer import METHODS, make_method
    names = split_names(methods)
    usable = [m for m in METHODS if not make_method(m).evaluation_only]
    unknown = [m for m in names if m not in usable]
    if not names or unknown:
        raise InputError("--methods", f"unknown method(s) {', '.join(unknown) or '(none)'}; "
                                      f"expected some of {', '.join(usable)}")
    return list(dict.fromkeys(names))


def existing_model_file(model):
    """Path(model), or InputError naming it when it is no file (a folder is named as one)."""
    if not Path(model).is_file():
        raise no_file(model, "model file", "no such model file")
    return Path(model)


def model_path(model, methods):
    """The model file to read (Path), or None when no method needs one; DEFAULT_MODEL when none
    is given."""
    if model is not None:
        return existing_model_file(model)
    if all(m in METHODS_NEEDING_NO_MODEL for m in methods):
        return None  # nothing to read: the default model is 9 MB and takes seconds to load
    if DEFAULT_MODEL.is_file():
        return DEFAULT_MODEL
    raise InputError("--model", f"no model given and the default {DEFAULT_MODEL} is missing "
                                "(make it with `flashbrdf train`)")


def run_inputs(scene_dir, model, methods, envmap=None):
    """Every file `run` of the capture `scene_dir` reads with these options: the scene's own
    (capture.Scene.input_files), the model it loads and --envmap. InputError as run raises it."""
    from flashbrdf import capture
    files = capture.load_scene(scene_dir).input_files()
    # the names unchecked: checking imports flashbrdf.infer (0.8 s), which a batch's client
    # otherwise never does; run refuses a bad name itself
    return files + [f for f in (model_path(model, split_names(methods)), envmap) if f is not None]


def inputs_fingerprint(scene_dir, options):
    """files_fingerprint of run_inputs for batch's run options (a dict: model, methods, envmap);
    {} when the scene cannot be read (no marker matches it: the capture is run, and fails with
    its reason)."""
    try:
        return files_fingerprint(run_inputs(scene_dir, options["model"], options["methods"],
                                            options.get("envmap")))
    except InputError:
        return {}


def samples_per_pixel(spp):
    """--spp of `render` and `run`: 64 when None; InputError below 1 (never silently 64) or
    above MAX_SPP (the sample pattern alone would not fit in memory)."""
    spp = 64 if spp is None else int(spp)
    if not 1 <= spp <= MAX_SPP:
        raise InputError("--spp", f"must be in 1..{MAX_SPP}, got {spp}")
    return spp


def fewer_materials_warning(segmentation, asked):
    """A warning line when --materials K kept fewer than K materials (a material explaining
    under 2% of the pixels goes, slice_extract.segment), else None."""
    if asked == "auto" or segmentation.k >= int(asked):
        return None
    why = str((segmentation.criterion or {}).get("reason", "")).partition("; ")[2]
    return (f"--materials {asked}: {segmentation.k} material(s) kept"
            + (f" ({why})" if why else "") + "; labels.json says why")


def materials_option(text):
    """--materials: "auto" or an int K in 1..64; InputError otherwise."""
    text = "auto" if text is None else str(text).strip()
    if text == "auto":
        return "auto"
    try:
        k = int(text)
    except ValueError:
        k = 0
    if k < 1 or k > 64:
        raise InputError("--materials", f"expected auto or a number of materials 1..64, got "
                                        f"{text!r}")
    return k
