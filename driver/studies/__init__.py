"""The studies behind the docs' tables and plots (``rayflex study``): ray order, BVH build times,
compressed images, instances; docs/architecture.md."""
