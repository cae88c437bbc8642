"""BVH build benchmark (driver.bvh_bench): build time and peak memory for the bunny and for
instanced bunnies (20 copies ~ 2 M, 50 copies ~ 5 M triangles), and tree quality before/after
(greedy vs SAH collapse) on the bunny's primary frame; prints one JSON object.

    python bench/bvh_build.py [--counts 0 20 50] [--size 256] [--no-quality] [--json PATH]
"""

from __future__ import annotations

import argparse
import json
import platform
import sys

from driver.bvh_bench import bvh_bench


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--counts", type=int, nargs="+", default=[0, 20, 50],
                    help="meshes to build: 0 = the bunny, k = k instanced bunnies")
    ap.add_argument("--size", type=int, default=256, help="frame size for the quality report")
    ap.add_argument("--no-quality", action="store_true", help="skip the before/after traces")
    ap.add_argument("--json", help="also write the JSON here")
    args = ap.parse_args(argv)
    try:
        result = bvh_bench(args.counts, quality=not args.no_quality, size=args.size)
    except (ValueError, OSError) as e:
        print(f"bvh_build: {e}", file=sys.stderr)
        return 2
    result["python"] = platform.python_version()
    text = json.dumps(result, indent=1)
    print(text)
    if args.json:
        with open(args.json, "w") as f:
            f.write(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
