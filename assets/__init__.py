"""Shipped data (URDF, meshes, textures, calibration), installed as the ``ihrcf_env.assets`` package."""
