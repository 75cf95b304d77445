"""Layer 3, lighting: the coefficient core, projection (R&H eq. 10), irradiance and the
quadratic form (eq. 7, 11-13), brute-force reference, lighting design, windows and export."""
