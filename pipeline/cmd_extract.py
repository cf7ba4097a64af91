"""`flashbrdf extract SCENE_DIR --out SLICE.csv`: the flash slice of a capture folder.

Writes the contract's slice.csv (with provenance comments) and SLICE.json beside it (coverage,
rejection counts, theta_d spread, timings). Nothing is written when extraction fails.
"""

import json
from pathlib import Path

import numpy as np

from brdf.atomic import write_text
from brdf.views import write_slice_csv


def extract(args):
    from slice_extract import ExtractOptions, extract_slice
    options = ExtractOptions(
        max_theta_d_deg=getattr(args, "max_theta_d", None) or ExtractOptions.max_theta_d_deg,
        min_cos=getattr(args, "min_cos", None) or ExtractOptions.min_cos)
    result = extract_slice(args.scene_dir, options)
    out = Path(args.out)
    cov = result.coverage
    comments = [
        f"flashbrdf extract {Path(args.scene_dir).resolve()}",
        f"pixels used {cov['pixels_used']}; bins filled {cov['bins_filled']}/90; theta_h observed "
        f"{cov['theta_h_deg_observed'][0]:.3f}..{cov['theta_h_deg_observed'][1]:.3f} deg",
        "rejected " + ", ".join(f"{k} {v}" for k, v in result.rejected.items()),
        f"estimator {options.estimator} (MAD k={options.outlier_k}); max theta_d "
        f"{options.max_theta_d_deg} deg; min cos {options.min_cos}",
    ]
    report = dict(result.report, slice_csv=str(out.resolve()),
                  spread=[[None if not np.isfinite(v) else float(v) for v in row]
                          for row in result.spread])
    json_path = out.with_suffix(".json")
    write_slice_csv(out, result.rho, result.n, comments=comments)
    write_text(json_path, json.dumps(report, indent=1) + "\n")
    return 0
