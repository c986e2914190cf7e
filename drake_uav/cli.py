"""Command line: ``drake-uav <command> ...``. A thin layer over library functions."""

from __future__ import annotations

import argparse
import sys

import numpy as np

__all__ = ["main"]


def _cmd_trim(args: argparse.Namespace) -> int:
    from drake_uav.linearization import mode_analysis
    from drake_uav.optimization.trim import TrimError, trim
    from drake_uav.vehicles.loading import load_fixed_wing

    params = load_fixed_wing(args.aircraft)
    try:
        result = trim(params, args.airspeed, np.radians(args.gamma), args.turn_rate)
    except TrimError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    e, a, r, t = result.controls
    print(f"{params.name} trim at Va = {args.airspeed:g} m/s, gamma = {args.gamma:g} deg, "
          f"turn rate = {args.turn_rate:g} rad/s")
    print(f"  alpha    = {np.degrees(result.alpha):8.4f} deg")
    print(f"  elevator = {np.degrees(e):8.4f} deg   aileron = {np.degrees(a):8.4f} deg")
    print(f"  rudder   = {np.degrees(r):8.4f} deg   throttle = {t:8.4f}")
    print(f"  residual = {result.residual:.2e}")
    if args.turn_rate == 0.0:
        print(mode_analysis(params, result).table())
    return 0


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="drake-uav",
        description="Small unmanned aircraft on Drake: trim, simulate, estimate and identify.",
    )
    sub = parser.add_subparsers(dest="command", metavar="<command>")
    trim = sub.add_parser("trim", help="trim a fixed wing and print its modes",
                          description="Trim a fixed-wing aircraft and print the trim and the "
                                      "classical modes of its linearisation.")
    trim.add_argument("--aircraft", default="aerosonde",
                      help="catalog name (aerosonde, unatrap, ...) or a params .toml file")
    trim.add_argument("--airspeed", type=float, default=25.0, help="airspeed [m/s]")
    trim.add_argument("--gamma", type=float, default=0.0, help="flight path angle [deg]")
    trim.add_argument("--turn-rate", type=float, default=0.0, help="turn rate [rad/s]")
    trim.set_defaults(handler=_cmd_trim)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``drake-uav`` console script; returns the exit code."""
    parser = _parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    try:
        return args.handler(args)
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
