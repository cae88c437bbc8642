"""The ray-order options of the RT-unit model (``--ray-order``, ``--ray-window``;
``driver.rtunit.order``)."""

from __future__ import annotations


def add_ray_order(p) -> None:
    """``--ray-order POLICY`` (choices: the policy table) and ``--ray-window W``."""
    from ..rtunit.order import DEFAULT_POLICY, DEFAULT_WINDOW, POLICIES
    p.add_argument("--ray-order", default=DEFAULT_POLICY, choices=list(POLICIES),
                   help="order in which rays enter the RT unit's ray pool: "
                        + "; ".join(f"{k}: {v.help}" for k, v in POLICIES.items())
                        + f" (default {DEFAULT_POLICY}; docs/rayorder.md)")
    p.add_argument("--ray-window", type=int, default=DEFAULT_WINDOW, metavar="W",
                   help=f"rays a sorting policy sorts together, or the affinity scheduler holds "
                        f"(at least the rays in flight) (default {DEFAULT_WINDOW})")


def ray_order_options(args, rays_in_flight: int) -> dict:
    """The checked options of ``add_ray_order`` as keyword arguments (one-line ValueError)."""
    from ..rtunit.order import policy
    if args.ray_window < 1:
        raise ValueError(f"--ray-window must be >= 1, got {args.ray_window}")
    if policy(args.ray_order).schedule and args.ray_window < rays_in_flight:
        raise ValueError(f"--ray-order {args.ray_order}: --ray-window ({args.ray_window}) must "
                         f"be at least --rays-in-flight ({rays_in_flight})")
    ordered = args.ray_order != "index"          # index order has no window
    return dict(ray_order=args.ray_order, ray_window=args.ray_window if ordered else None)
