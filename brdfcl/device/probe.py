"""Child process of brdfcl.device.width: build the default model at one vector width and self-test it.

Run as ``python -m brdfcl.device.probe --device P:D --real float --width 16``; prints one JSON
line.  A separate process because a program built for the wrong target may crash."""
from __future__ import annotations

import argparse
import json
import sys

from brdfcl.device import selftest
from brdfcl.device.build import ABI_WARNING, build_log
from brdfcl.device.engine import Engine
from brdfcl.device.errors import ProgramError
from brdfcl.model.compose import DEFAULT_MODEL


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m brdfcl.device.probe")
    ap.add_argument("--device", required=True)
    ap.add_argument("--real", choices=("float", "double"), default="float")
    ap.add_argument("--width", type=int, required=True)
    a = ap.parse_args(argv)
    try:
        eng = Engine(DEFAULT_MODEL, device=a.device, real=a.real, verify=False, vw=a.width)
    except ProgramError as e:
        print(json.dumps({"ok": False, "detail": e.cause, "log": str(e.log) if e.log else None}))
        return 0
    res = selftest.check(eng)
    n_abi = build_log(eng.program, eng.device).count(ABI_WARNING)
    print(json.dumps({"ok": res.ok, "detail": str(res), "max_error": res.max_error, "abi_warnings": n_abi}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
