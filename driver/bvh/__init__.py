"""The BVH4 builder's kernels (``build``), their parameters (``params``) and the build benchmark
(``bench``); ``driver.bvh4`` is the entry point."""
