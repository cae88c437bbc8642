"""Build parameters shared by the two BVH builders (``driver.bvh4``'s numpy builder and the numba
kernels of ``driver.bvh_build``), which must make the same tree."""

SWEEP_MAX = 8          # nodes of <= 8 primitives: exact SAH sweep instead of bins
