"""Figures: ``python -m planner_tools.figures candidates --out candidates.png``.

``candidates`` draws the candidates of Algorithm 4 (``naive``) and Algorithm 5 (``transf_kappa``)
side by side on the demo U-turn, whose inner side is wider than its radius: naive candidates that run
backwards or cross themselves are drawn in red, the rest in blue
(:func:`planner_tools.render.candidates_figure`). ``road-candidates`` does the same for the corridor the
lane decision borrows on a U-turn whose lane a parked car blocks and whose road is wider on the inside
than the radius (:func:`planner_tools.render.road_candidates_figure`). Needs the optional extra
``tools``; without it, says how to install it (exit status 2).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from planner_tools.extras import TOOLS, MissingExtraError


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``python -m planner_tools.figures``; returns the exit status."""
    parser = argparse.ArgumentParser(prog="python -m planner_tools.figures", description=__doc__)
    sub = parser.add_subparsers(dest="figure", required=True)
    cand = sub.add_parser("candidates", help="Algorithm 4 vs 5 candidates on the demo U-turn")
    cand.add_argument("--out", type=Path, default=Path("candidates.png"))
    cand.add_argument("--num-candidates", type=int, default=40)
    cand.add_argument("--seed", type=int, default=0)
    road = sub.add_parser(
        "road-candidates", help="Algorithm 4 vs 5 candidates of a borrowed road on a tight U-turn"
    )
    road.add_argument("--out", type=Path, default=Path("road_candidates.png"))
    road.add_argument("--num-candidates", type=int, default=40)
    road.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    try:
        TOOLS.require("drawing")
    except MissingExtraError as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return 2
    from planner_tools import render  # the extra `tools`, checked above

    if args.figure == "candidates":
        path = render.candidates_figure(args.out, num_candidates=args.num_candidates, seed=args.seed)
        print(f"wrote {path}")
    elif args.figure == "road-candidates":
        path = render.road_candidates_figure(args.out, num_candidates=args.num_candidates, seed=args.seed)
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
