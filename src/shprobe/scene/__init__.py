"""Layer 4, scene: camera, meshes and materials, the one ray caster, and diffuse rendering."""
