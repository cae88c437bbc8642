"""Build parameters shared by the stages of the BVH build: the two binary builders
(``driver.bvh.reference``'s numpy builder and the numba kernels of ``driver.bvh.build``), which
must make the same tree, and the collapse and image writers of the 4-wide tree."""

SWEEP_MAX = 8          # nodes of <= 8 primitives: exact SAH sweep instead of bins
WIDTH = 4              # children per wide node
