"""Export a MERL table for other renderers: Mitsuba 3 (tabulated plugin, `principled`), Blender, glTF.

export_table(table, table_path, out_dir, formats) writes into an existing folder:
- "mitsuba":    mitsuba_tabulated.xml (the flashbrdf_tabulated plugin reading the table itself) and
                mitsuba_principled.xml (Mitsuba's `principled` with the fitted parameters);
- "principled": principled.json (fitted parameters in Mitsuba names, the Blender 4 mapping, "fit");
- "gltf":       material.gltf (glTF 2.0, one pbrMetallicRoughness material + KHR extensions).
Any format but "mitsuba" alone needs the fit (brdf.principled_fit); its quality is measured
twice: the 2D LAB-log error of the fitted model against the table, and the log-CIELAB Delta E
between spheres under pisa rendered with the fitted model and with the table.
"""

import json
import os
import time
from xml.sax.saxutils import quoteattr

import numpy as np

from flashbrdf.files.atomic import write_text
from flashbrdf.files.errors import InputError
from flashbrdf.files.outputs import check_outputs, staged_output_dir
from flashbrdf.brdf.merl import read_merl
from flashbrdf.brdf.metrics import brdf_error
from flashbrdf.brdf.models.principled import MITSUBA_LUMINANCE, PARAMETER_NAMES, clearcoat_alpha, \
    eta_from_specular, tabulate_principled
from flashbrdf.brdf.models.principled_fit import FIT_OFFSET, fit_principled
from flashbrdf.brdf.views import table_2d
from flashbrdf.render.compare import compare_images
from flashbrdf.render.scene_render import render_sphere, sphere_view

FORMATS = ("mitsuba", "principled", "gltf")
FILES = {"mitsuba": ("mitsuba_tabulated.xml", "mitsuba_principled.xml"),
         "principled": ("principled.json",), "gltf": ("material.gltf",)}
# 256 spp: both spheres draw BRDF samples from their own table, so their noise does not cancel;
# at 64 spp it read white-paint's fit 1.17 against 0.67 converged (1024 spp), at 256 0.77
RENDER_SIZE, RENDER_SPP = 96, 256
USED = 0.01  # a lobe weight below this is treated as unused (no glTF extension for it)
MITSUBA_USAGE = ("Mitsuba 3: `pip install mitsuba` (in a checkout: `pip install -e "
                 "\".[mitsuba]\"`), then in Python `import mitsuba as mi; "
                 "mi.set_variant(\"llvm_ad_rgb\"); import flashbrdf.render.mitsuba_bsdf as m; "
                 "m.register(); bsdf = mi.load_file(\"mitsuba_tabulated.xml\")` (llvm_ad_rgb "
                 "needs LLVM >= 16: on Debian 12 `apt-get install libllvm19`, which "
                 "flashbrdf.render.mitsuba_bsdf finds by itself); mitsuba_principled.xml needs "
                 "no plugin.")


def parse_formats(text):
    """The tuple of format names in a comma-separated `--formats` value; InputError if unknown."""
    names = [f.strip() for f in str(text).split(",") if f.strip()]
    unknown = [f for f in names if f not in FORMATS]
    if not names or unknown:
        raise InputError("--formats", f"unknown format(s) {', '.join(unknown) or '(none)'}; "
                                      f"expected some of {','.join(FORMATS)}")
    return tuple(dict.fromkeys(names))


def output_files(formats):
    """The file names export writes for `formats`, in order."""
    return [name for f in formats for name in FILES[f]]


def tint_colour(base_color):
    """base_color / luminance (Mitsuba's tint colour), white for black; (3,)."""
    base = np.asarray(base_color, dtype=np.float64)
    lum = float(base @ MITSUBA_LUMINANCE)
    return base / lum if lum > 0 else np.ones(3)


def coat_roughness(clearcoat_gloss):
    """The roughness (GGX alpha = roughness²) of a GGX coat, glTF's and Blender's, whose highlight
    peaks as high as Mitsuba's GTR1 clearcoat of alpha a = lerp(0.1, 0.001, gloss).

    Both distributions are normalised, so at one alpha GGX's peak 1 / (π a²) is −ln(a²) / (1 − a²)
    times GTR1's (4.6× at a = 0.1, 14× at 0.001): the same alpha would make the coat's highlight
    that much brighter. Matching the peak, GGX's alpha is a √(−ln(a²) / (1 − a²)); GTR1's long
    tail is what GGX cannot carry."""
    a = clearcoat_alpha(clearcoat_gloss)
    return float(np.sqrt(a * np.sqrt(-np.log(a * a) / (1.0 - a * a))))


def blender_parameters(params):
    """Blender 4 Principled BSDF input values (by Blender's input names) for Mitsuba parameters.

    Blender 4 replaced `Specular` by an IOR (`IOR`, with `Specular IOR Level` 0.5 = as the IOR
    says) and made the tints colours; the tint colours here are lerp(white, base/lum, tint), the
    colour Mitsuba's tint fraction blends towards. Mitsuba's clearcoat is Blender's coat at
    IOR 1.5 (Schlick R0 = 0.04) with the roughness of coat_roughness (the same peak). Mitsuba's
    sheen is Burley's Schlick sheen; Blender 4's is a microfibre lobe, so `Sheen Weight` is
    approximate.
    """
    base = [float(c) for c in params["base_color"]]
    tint = tint_colour(base)
    spec_tint = [float(v) for v in 1.0 + params["spec_tint"] * (tint - 1.0)]
    sheen_tint = [float(v) for v in 1.0 + params["sheen_tint"] * (tint - 1.0)]
    return {"Base Color": base + [1.0], "Metallic": params["metallic"],
            "Roughness": params["roughness"], "IOR": float(eta_from_specular(params["specular"])),
            "Specular IOR Level": 0.5, "Specular Tint": spec_tint + [1.0],
            "Sheen Weight": params["sheen"], "Sheen Tint": sheen_tint + [1.0],
            "Coat Weight": params["clearcoat"],
            "Coat Roughness": coat_roughness(params["clearcoat_gloss"]), "Coat IOR": 1.5}


def gltf_material(params, name="flashbrdf"):
    """A glTF 2.0 document (dict) with one material for Mitsuba principled parameters.

    pbrMetallicRoughness carries base colour, metallic and roughness (glTF's roughness is also
    squared to GGX alpha); KHR_materials_ior carries eta, KHR_materials_specular the specular
    tint colour, KHR_materials_clearcoat and KHR_materials_sheen their lobes, each only when used.
    The document has no mesh.
    """
    base = [float(np.clip(c, 0.0, 1.0)) for c in params["base_color"]]
    tint = tint_colour(base)
    extensions = {}
    eta = float(eta_from_specular(params["specular"]))
    if abs(eta - 1.5) > 1e-3:
        extensions["KHR_materials_ior"] = {"ior": eta}
    if params["spec_tint"] > USED:
        colour = np.clip(1.0 + params["spec_tint"] * (tint - 1.0), 0.0, None)
        extensions["KHR_materials_specular"] = {"specularFactor": 1.0,
                                                "specularColorFactor": [float(c) for c in colour]}
    if params["clearcoat"] > USED:
        extensions["KHR_materials_clearcoat"] = {
            "clearcoatFactor": float(params["clearcoat"]),
            "clearcoatRoughnessFactor": coat_roughness(params["clearcoat_gloss"])}
    if params["sheen"] > USED:
        # glTF caps the colour at 1: a saturated tint (base / luminance reaches 4.7 for pure red)
        # is scaled down whole, so its hue stays the one Mitsuba and Blender get
        colour = np.clip(params["sheen"] * (1.0 + params["sheen_tint"] * (tint - 1.0)), 0.0, None)
        colour = colour / max(1.0, float(colour.max()))
        extensions["KHR_materials_sheen"] = {"sheenColorFactor": [float(c) for c in colour],
                                             "sheenRoughnessFactor": 0.5}
    material = {"name": name, "pbrMetallicRoughness": {
        "baseColorFactor": base + [1.0], "metallicFactor": float(params["metallic"]),
        "roughnessFactor": float(params["roughness"])}}
    if extensions:
        material["extensions"] = extensions
    doc = {"asset": {"version": "2.0", "generator": "flashbrdf export"}, "materials": [material]}
    if extensions:
        doc["extensionsUsed"] = sorted(extensions)
    return doc


def mitsuba_principled_xml(params):
    """Mitsuba 3 scene fragment: a `principled` BSDF with these parameters."""
    r, g, b = (float(c) for c in params["base_color"])
    lines = ['<bsdf type="principled" id="flashbrdf_principled" version="3.0.0">',
             f'    <rgb name="base_color" value="{r:.6g}, {g:.6g}, {b:.6g}"/>']
    lines += [f'    <float name="{n}" value="{float(params[n]):.6g}"/>' for n in PARAMETER_NAMES[1:]]
    return "\n".join(lines + ["</bsdf>"]) + "\n"


def mitsuba_tabulated_xml(table_path):
    """Mitsuba 3 scene fragment: the flashbrdf_tabulated plugin reading `table_path`."""
    path = quoteattr(os.path.abspath(os.fspath(table_path)))
    return ("<!-- Needs the flashbrdf plugin: import flashbrdf.render.mitsuba_bsdf as m; m.register() -->\n"
            '<bsdf type="flashbrdf_tabulated" id="flashbrdf_tabulated" version="3.0.0">\n'
            f'    <string name="filename" value={path}/>\n</bsdf>\n')


def fit_quality(table, params, envmap=None, size=RENDER_SIZE, spp=RENDER_SPP, seed=0):
    """{"lab_log_2d", "render": {...} or None}: the fitted model against the table.

    lab_log_2d: brdf.metrics' LAB-log error between the 2D views (mean over phi_d) of the
    tabulated fit and of the table. render: delta_e_log_mean between spheres under `envmap` (a
    lat-long map's path; None skips it) rendered with the tabulated fit and with the table, same
    seed. Each draws its BRDF samples from its own table, so render noise adds to the figure: at
    RENDER_SPP, up to ~1.2x the converged value on a diffuse paint, ~1.01x on glossy ones.
    """
    fitted_table = tabulate_principled(params)
    out = {"lab_log_2d": brdf_error(table_2d(fitted_table), table_2d(table), "log", "lab"),
           "render": None}
    if envmap is not None:
        start = time.perf_counter()
        reference = render_sphere(table, envmap, size=size, spp=spp, seed=seed)
        fitted = render_sphere(fitted_table, envmap, size=size, spp=spp, seed=seed)
        metrics, _ = compare_images(fitted, reference, sphere_view(size)[0])
        out["render"] = {"envmap": os.path.basename(os.fspath(envmap)),
                         "delta_e_log_mean": metrics["delta_e_log_mean"], "size": size,
                         "spp": spp, "seconds": time.perf_counter() - start,
                         "images": {"tabulated": reference, "fitted": fitted}}
    return out


def check_table(table, table_path):
    """InputError naming the file when the table has no valid bin."""
    if not np.any(np.all(np.isfinite(table), axis=-1)):
        raise InputError(table_path, "the table has no valid bin (every value is no-data)")


def export_table(table, table_path, out_dir, formats=FORMATS, envmap=None, final_path=None,
                 name=None):
    """Write the files of `formats` for a MERL table (90, 90, 180, 3) into the folder out_dir.

    table_path: the table's file (mitsuba_tabulated.xml points to it). final_path: where that
    file will be once a staged output folder is renamed into place (`run --export`), recorded
    instead of table_path (default: table_path). envmap: for the render check (None skips it).
    name: the glTF material's name (default: the table file's stem).
    Returns {"files": [...], "params": dict, "fit": dict,
    "images": {"tabulated", "fitted"} sphere renders, or None without envmap,
    "warnings": [one line each]}.
    """
    check_table(table, table_path)
    table_path = table_path if final_path is None else final_path  # the path the files record
    files, images, warnings = [], None, []
    if "mitsuba" in formats:
        write_text(os.path.join(out_dir, FILES["mitsuba"][0]), mitsuba_tabulated_xml(table_path))
        files.append(FILES["mitsuba"][0])
        if "$" in os.path.abspath(os.fspath(table_path)):
            # Mitsuba's XML parser substitutes $name in every attribute and has no escape for it
            warnings.append(f"{FILES['mitsuba'][0]}: the table's path holds '$', which "
                            "Mitsuba's load_file reads as a scene parameter: load it with "
                            "mi.load_dict({'type': 'flashbrdf_tabulated', 'filename': ...}) or "
                            "keep the table where its path has no '$'")
    # Every format holds the fit (mitsuba: mitsuba_principled.xml).
    result = fit_principled(table)
    params = result["params"]
    quality = fit_quality(table, params, envmap)
    render = quality["render"]
    if render is not None:
        images = render.pop("images")
    fit = {"lab_log_2d": quality["lab_log_2d"],
           "render_delta_e_log": None if render is None else render["delta_e_log_mean"],
           "render": render, "optimiser": result["optimiser"],
           "seconds": result["seconds"], "cpu_seconds": result["cpu_seconds"],
           "bins": result["bins"], "starts": result["starts"],
           "evaluations": result["evaluations"],
           "loss": f"sum of cos_i cos_o (ln(rho_fit + {FIT_OFFSET}) "
                   f"- ln(rho_table + {FIT_OFFSET}))^2"}
    if "mitsuba" in formats:
        write_text(os.path.join(out_dir, FILES["mitsuba"][1]), mitsuba_principled_xml(params))
        files.append(FILES["mitsuba"][1])
    if "principled" in formats:
        doc = {**params, "blender": blender_parameters(params), "fit": fit,
               "table": os.path.abspath(os.fspath(table_path))}
        write_text(os.path.join(out_dir, "principled.json"), json.dumps(doc, indent=2) + "\n")
        files.append("principled.json")
    if "gltf" in formats:
        doc = gltf_material(params, name=name or os.path.splitext(os.path.basename(table_path))[0])
        write_text(os.path.join(out_dir, "material.gltf"), json.dumps(doc, indent=2) + "\n")
        files.append("material.gltf")
    return {"files": files, "params": params, "fit": fit, "images": images, "warnings": warnings}


def export_brdf(brdf_path, out_dir, formats=FORMATS, envmap=None, force=False, final_path=None,
                name=None):
    """Export a MERL table into out_dir (an earlier export there is replaced only with force); the
    result dict of render.export.export_table. envmap: a lat-long map (`export --envmap`) for the
    sphere render check of the fit, or None to skip it (nothing outside the project is read
    unless a flag names it). final_path: where brdf_path will be once its staged folder is
    renamed into place, recorded in the files instead of brdf_path (`run --export`); name: the
    glTF material's name (default: the table file's stem)."""
    check_outputs(inputs=[brdf_path, envmap], outputs=[out_dir], folders=[out_dir])
    table = read_merl(brdf_path)
    if envmap is not None:
        from flashbrdf.render.envmap import read_envmap_pixels
        read_envmap_pixels(envmap)  # bad input before any work: missing, unreadable or not 2:1
    with staged_output_dir(out_dir, force=force, command="export") as tmp:
        result = export_table(table, brdf_path, tmp, formats, envmap=envmap,
                              final_path=final_path, name=name)
    return result
