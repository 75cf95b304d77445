"""Layer 2, probes: image I/O, every image layout's directions and solid angles (``Env``),
procedural environments and the R&H preset tables. Imports only ``sh`` and the base modules."""
