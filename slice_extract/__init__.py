"""slice_extract: from flash pixels and known geometry to the 1D BRDF slice rho(theta_h).

Takes a loaded capture (photos, masks, camera, geometry hits).
Gives the 90-bin theta_d ~ 0 slice with a robust per-bin estimate, sample counts, spread and a
coverage report; written as the contract's `slice.csv` plus a JSON sidecar.
"""
