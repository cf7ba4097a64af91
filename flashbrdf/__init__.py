"""flashbrdf: a flash photograph of known geometry -> a full measured BRDF (a MERL table).

Georgoulis et al., "A Gaussian Process Latent Variable Model for BRDF Inference" (ICCV 2015).

Subpackages (each a folder of the repository, installed under this one import name):
- flashbrdf.brdf           the shared data model: MERL tables, angles, colour, metrics, BRDF models
- flashbrdf.capture        a capture folder (scene.json) -> calibrated linear radiance; importers
- flashbrdf.slice_extract  flash pixels + geometry -> the theta_d = 0 slice rho(theta_h); materials
- flashbrdf.infer          a slice -> a full 2D/3D BRDF (DS-GPLVM and the baselines)
- flashbrdf.render         re-render a capture with a BRDF; image comparison; export
- flashbrdf.pipeline       `run` and `batch`: the stages wired together, and the report
- flashbrdf.experiments    the paper's protocols (`evaluate`)
- flashbrdf.cli            the `flashbrdf` command

Importing this package imports no stage: `flashbrdf --help` stays fast.
"""

# The one place the version is set (pyproject.toml reads it): importlib.metadata would cost
# `flashbrdf --help` a sixth of a second.
__version__ = "0.1.0"
