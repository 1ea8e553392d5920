"""The `brdfcl` command line.  Errors are one line naming the problem (tracebacks with --debug)."""
from __future__ import annotations

import argparse
import sys

from . import __version__


class UsageError(Exception):
    """A problem the user can fix, printed as one line."""


def cmd_info(args):
    import pyopencl as cl

    from .device import describe, pick_device
    print(f"brdfcl {__version__}, pyopencl {cl.VERSION_TEXT}")
    for line in describe():
        print(line)
    p, d = pick_device(args.device)
    print(f"default device: {d.name} on {p.name} ({p.version})")
    return 0


def cmd_synth(args):
    from .synth import DEMO, write_synth
    mats = args.materials.split(",") if args.materials else None
    if mats:
        bad = [m for m in mats if m not in DEMO]
        if bad:
            raise UsageError(f"unknown demo material(s) {', '.join(bad)}; valid: {', '.join(DEMO)}")
    write_synth(args.out, mats, noise=args.noise, missing=args.missing, seed=args.seed)
    print(f"wrote {len(mats or DEMO)} materials and truth.json to {args.out}")
    return 0


def build_parser():
    ap = argparse.ArgumentParser(prog="brdfcl", description=__doc__)
    ap.add_argument("--version", action="version", version=f"brdfcl {__version__}")
    ap.add_argument("--debug", action="store_true", help="show tracebacks")
    sub = ap.add_subparsers(dest="cmd", required=True)

    p = sub.add_parser("info", help="list OpenCL platforms and devices")
    p.add_argument("--device", default=None, help="device index or name (default: PoCL CPU)")
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("synth", help="write the synthetic demo database (MERL format)")
    p.add_argument("out", help="output folder")
    p.add_argument("--noise", type=float, default=0.0, help="relative Gaussian noise (default 0)")
    p.add_argument("--missing", type=float, default=0.0, help="fraction of cells marked missing")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--materials", default=None, help="comma-separated subset of the demo materials")
    p.set_defaults(func=cmd_synth)
    return ap


def main(argv=None):
    ap = build_parser()
    args = ap.parse_args(argv)
    debug = getattr(args, "debug", False)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("brdfcl: interrupted", file=sys.stderr)
        return 130
    except Exception as e:  # one line unless --debug
        if debug:
            raise
        from .device import DeviceError
        from .merl import MerlError
        from .model import ModelError
        known = (UsageError, MerlError, ModelError, DeviceError, OSError, ValueError)
        kind = "" if isinstance(e, known) else f"{type(e).__name__}: "
        print(f"brdfcl: error: {kind}{e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
