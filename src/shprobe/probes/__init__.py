"""Layer 2, probes: pictures in, pictures out. Image I/O (`shprobe.probes.images`, the formats in
`shprobe.probes.codecs`, display encoding in `shprobe.probes.tonemap`, streamed rows in
`shprobe.probes.streaming`), every image layout's directions and solid angles
(`shprobe.probes.layouts`), environment maps as data (`shprobe.probes.env`: ``Env``, ``load_env``),
procedural environments, the R&H preset tables and labelled figures. Imports only ``sh`` and the
base modules."""
