"""`flashbrdf extract SCENE_DIR --out SLICE.csv`: the flash slice of a capture folder.

Writes the contract's slice.csv (with provenance comments) and SLICE.json beside it (coverage,
rejection counts, theta_d spread, timings). Nothing is written when extraction fails.
"""

import json
from pathlib import Path

import numpy as np

from brdf.atomic import write_text
from brdf.errors import InputError
from brdf.views import write_slice_csv
from pipeline.safety import check_outputs, sidecar_json


def _options(args):
    from slice_extract import ExtractOptions
    max_theta_d = getattr(args, "max_theta_d", None)
    min_cos = getattr(args, "min_cos", None)
    if max_theta_d is not None and not 0 < max_theta_d <= 90:
        raise InputError("--max-theta-d", f"expected degrees in (0, 90], got {max_theta_d}")
    if min_cos is not None and not 0 <= min_cos < 1:
        raise InputError("--min-cos", f"expected a value in [0, 1), got {min_cos}")
    silhouette = getattr(args, "silhouette_px", None)
    if silhouette is not None and not 0 <= silhouette <= 50:
        raise InputError("--silhouette-px", f"expected 0..50 pixels, got {silhouette}")
    return ExtractOptions(
        silhouette_px=ExtractOptions.silhouette_px if silhouette is None else silhouette,
        max_theta_d_deg=ExtractOptions.max_theta_d_deg if max_theta_d is None else max_theta_d,
        min_cos=ExtractOptions.min_cos if min_cos is None else min_cos)


def extract(args):
    import capture
    from slice_extract import extract_slice
    options = _options(args)
    scene = capture.load_scene(args.scene_dir)
    check_outputs(inputs=[args.scene_dir, *scene.input_files()],
                  outputs=[args.out, sidecar_json(args.out)])
    result = extract_slice(scene, options)
    write_extraction(args.out, args.scene_dir, result, options)
    return 0


def write_extraction(out, scene_dir, result, options, final_path=None):
    """Write slice.csv (with provenance comments) and the JSON sidecar beside it, both or neither.

    final_path: where slice.csv will end up, when `out` is in a staged folder (run) that is
    renamed afterwards; the sidecar records it. Default `out`.

    Returns the slice as written: rho (90, 3) in 1/sr, NaN where empty.
    """
    out = Path(out)
    cov = result.coverage
    comments = [
        f"flashbrdf extract {Path(scene_dir).resolve()}",
        f"pixels used {cov['pixels_used']}; bins filled {cov['bins_filled']}/90; theta_h observed "
        f"{cov['theta_h_deg_observed'][0]:.3f}..{cov['theta_h_deg_observed'][1]:.3f} deg",
        "rejected " + ", ".join(f"{k} {v}" for k, v in result.rejected.items()),
        f"estimator {options.estimator} (MAD k={options.outlier_k}); max theta_d "
        f"{options.max_theta_d_deg} deg; min cos {options.min_cos}; silhouette "
        f"{options.silhouette_px} px",
    ]
    clamped = result.report.get("clamped_negative_bins", 0)
    if clamped:
        comments.append(f"{clamped} bin(s) had a slightly negative estimate (noise around 0) and "
                        "are written as 0")
    rho = result.rho
    report = dict(result.report, slice_csv=str(Path(final_path or out).resolve()),
                  spread=[[None if not np.isfinite(v) else float(v) for v in row]
                          for row in result.spread])
    json_path = Path(sidecar_json(out))  # --out x.json: keep the slice, x.report.json beside it
    text = json.dumps(report, indent=1) + "\n"
    write_slice_csv(out, rho, result.n, comments=comments)
    try:
        write_text(json_path, text)
    except BaseException:
        out.unlink(missing_ok=True)  # never leave half of the output behind
        raise
    return rho
