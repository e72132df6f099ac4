"""`euc-ros session init`: write a commented session file from the rider's measurements and the EUC's."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from euc_ros.core.anthropometry import BODIES, REFERENCE
from euc_ros.core.errors import ConfigError
from euc_ros.core.model.session_template import EUC_HOWTO, NameMap, RiderMeasures, render_session
from euc_ros.core.session import parse_session
from euc_ros.core.yamlfile import parse_yaml


def option(key: str) -> str:
    """The ``session init`` option of an EUC key (``body`` -> ``--euc-body``, ``h0`` -> ``--h0``)."""
    return "--euc-body" if key == "body" else f"--{key.replace('_', '-')}"


HELP = "write a session file (rider segments from body mass, height and sex; the EUC's measured values)"

EPILOG = f"""rider bodies (pass --name BODY=MOTIVE_NAME for each one your lab names otherwise):
{chr(10).join(f'  {b:4s} {what}' for b, what in BODIES.items())}

segment masses and centres of mass: {REFERENCE}.
EUC values not given take the EUC paper's (Table 3) and say so in the file. How to measure each:
{chr(10).join(f'  {option(k):24s} {v}' for k, v in EUC_HOWTO.items())}

example:
  euc-ros session init --mass 72 --height 1.78 --sex male --world-up z --name H=Helmet \\
      --wheel-radius 0.203 --body-mass 21.5 --out session.yaml
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``euc-ros session``."""
    parser.epilog = EPILOG
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    p = sub.add_parser("init", help="write a new commented session file", epilog=EPILOG,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--mass", type=float, required=True, metavar="KG", help="rider body mass with gear [kg]")
    p.add_argument("--height", type=float, required=True, metavar="M", help="rider standing height [m]")
    p.add_argument("--sex", required=True, choices=("male", "female"), help="selects the segment table")
    p.add_argument("--helmet", type=float, default=0.0, metavar="M",
                   help="helmet top above the head's vertex [m] (the head body's pivot is on the helmet) [0]")
    p.add_argument("--world-up", choices=("y", "z"), default="y", help="Motive's up axis [y, Motive's default]")
    p.add_argument("--rate", type=float, default=120.0, metavar="HZ", help="capture rate [Hz] [120]")
    p.add_argument("--name", action="append", default=[], metavar="BODY=MOTIVE_NAME",
                   help="the lab's Motive name of a rider body (repeatable), e.g. CHR=RightShoulder")
    for key in EUC_HOWTO:
        if key == "pivot_to_wheel_center":
            p.add_argument(option(key), type=float, nargs=3, metavar=("X", "Y", "Z"),
                           help="wheel centre from the EUC pivot, EUC body frame [m]")
        elif key == "body":
            p.add_argument(option(key), metavar="NAME", help="the EUC's rigid-body name in Motive [E]")
        else:
            p.add_argument(option(key), type=float, metavar="VALUE", help=f"EUC {key} (SI)")
    p.add_argument("--out", required=True, metavar="FILE", help="session YAML to write ('-' for standard output)")
    p.add_argument("--force", action="store_true", help="replace an existing file")


def main(args: argparse.Namespace) -> int:
    """Write the session and check that it reads back."""
    euc = {}
    for key in EUC_HOWTO:
        value = getattr(args, "euc_body" if key == "body" else key, None)
        if value is not None:
            euc[key] = tuple(value) if key == "pivot_to_wheel_center" else value
    text = render_session(RiderMeasures(args.mass, args.height, args.sex, args.helmet), euc,
                          names=NameMap.parse(args.name).names, world_up=args.world_up, rate_hz=args.rate)
    where = "standard output" if args.out == "-" else args.out
    parse_session(parse_yaml(text, where), where)     # what is written always validates
    if args.out == "-":
        sys.stdout.write(text)
        return 0
    out = Path(args.out)
    if out.exists() and not args.force:
        raise ConfigError("exists already: give --force to replace it, or another --out", path=out)
    if out.exists() and out.is_dir():
        raise ConfigError("is a directory: give a file name", path=out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text, encoding="utf-8")
    missing = [k for k in EUC_HOWTO if k not in euc]
    print(f"session init: wrote {out}" + (f"; EUC values to measure (the paper's for now): {', '.join(missing)}"
                                          if missing else ""))
    return 0
