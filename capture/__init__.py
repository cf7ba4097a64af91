"""capture: from a capture folder on disk to calibrated, linear radiance.

Takes a `scene.json` folder (see ../shared/spec/INTERFACES.md): camera, geometry and photos.
Gives a validated scene description, float32 linear-RGB photos with per-pixel "usable" masks
(ambient already subtracted from flash photos), camera rays, and ray-geometry hits (Embree).
"""
