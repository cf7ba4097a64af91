"""render: re-render a capture's geometry with a tabulated or analytic BRDF.

Takes a scene (camera, geometry, lights: point, directional, environment map) and a BRDF.
Gives HDR images in the photos' pixel units (Monte Carlo with MIS for environment maps) and image
comparisons (log-CIELAB Delta E, relative RMSE).
"""
