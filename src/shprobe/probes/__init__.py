"""Layer 2, probes: pictures in, pictures out. Image I/O (:mod:`.images`, the formats in
:mod:`.codecs`, display encoding in :mod:`.tonemap`, streamed rows in :mod:`.streaming`), every
image layout's directions and solid angles (:mod:`.layouts`), environment maps as data
(:mod:`.env`: ``Env``, ``load_env``), procedural environments, the R&H preset tables and
labelled figures. Imports only ``sh`` and the base modules."""
