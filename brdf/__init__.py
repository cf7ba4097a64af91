"""brdf: the shared data model of flashbrdf. Every stage imports it; it imports no stage.

- merl: MERL `.binary` tables (read, write, bin centres, validity mask)
- rusinkiewicz: the one set of conversions (theta_h, theta_d, phi_d) <-> direction pairs, cosines
- angles: those angles -> MERL bin indices (and the conversions, re-exported)
- frame: Frame, an orthonormal shading frame (from_normal, to_local, to_world)
- lookup: evaluating a 3D or 2D table at arbitrary angles or directions
- views: the 1D flash slice, 2D and 3D views; slice.csv
- colour: linear sRGB <-> CIELAB, the log-CIELAB feature map
- metrics: the paper's Table 1 / Table 2 errors
- models: BRDF models with evaluate / sample / pdf (Lambert, GGX, tabulated, Mitsuba's principled)
- shadowing: the Ashikhmin-Premoze shadowing term over MERL's bins (baselines, row blend)
"""
