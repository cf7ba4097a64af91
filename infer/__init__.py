"""infer: from a 1D BRDF slice to a full 2D/3D BRDF.

Takes training BRDF views (1D, 2D, optionally 3D, in the `brdf` feature space) and a new slice.
Gives the DS-GPLVM of Georgoulis et al. 2015 and the baselines (pca, noll, chandraker, ashikhmin,
oracle) behind one fit/predict interface, and the Table 1 evaluation.
"""
