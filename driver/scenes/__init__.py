"""Scenes: loading (TOML, mesh files, built-ins), the rendering built-ins, cameras and the
counter-based sampler."""
