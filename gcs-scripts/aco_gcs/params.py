"""Parameters (pymavlink): `dump FILE` writes every parameter of the vehicle as `NAME VALUE` lines (the
MAVProxy / QGroundControl text style; `-` for standard output), `load FILE` sets each (PARAM_SET in the
type the vehicle declares, as PX4's: INT32 with its bytes as they are for an integer or a switch, REAL32 for
a real) and checks the echoed PARAM_VALUE, reporting refusals; `get NAME` and `set NAME VALUE` do one. With
--plant they talk to the plant's SIM_ parameters (UDP 19550+N) instead of the autopilot. Exit 1 if any
set is refused or a parameter is not answered, 2 if no vehicle (or plant) answers.

`load` reads `NAME VALUE` lines (space, tab or comma separated; `#` starts a comment) and QGroundControl's
tab-separated `SYSID COMPID NAME VALUE TYPE` lines."""

import argparse
import sys

from .link import (
    AUTOPILOT_COMPONENT,
    CheckFailed,
    GcsError,
    Params,
    Plant,
    Vehicle,
    add_link_args,
    float32,
    run_main,
    same_float32,
)


def parser():
    p = argparse.ArgumentParser(
        prog="aco-params", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_link_args(p)
    p.add_argument("--plant", action="store_true", help="the plant's SIM_ parameters (UDP 19550+N), not the vehicle's")
    sub = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    dump = sub.add_parser("dump", help="write every parameter to FILE (`-`: standard output)")
    dump.add_argument("file")
    load = sub.add_parser("load", help="set every parameter in FILE and verify the echoes")
    load.add_argument("file")
    get = sub.add_parser("get", help="print one parameter")
    get.add_argument("name")
    put = sub.add_parser("set", help="set one parameter and verify the echo")
    put.add_argument("name")
    put.add_argument("value", type=float)
    return p


def format_value(value):
    """A value (a REAL32's, or a decoded INT32's) as the shortest text that reads back to the same f32."""
    value = float32(value)
    if value == int(value) and abs(value) < 1e7:
        return str(int(value))
    for digits in range(6, 10):
        text = f"{value:.{digits}g}"
        if float32(float(text)) == value:
            return text
    return repr(value)


def parse_file(text):
    """[(name, value)] from a parameter file; raises GcsError on a malformed line."""
    out = []
    for number, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        fields = line.replace(",", " ").split()
        if len(fields) == 5 and fields[0].isdigit() and fields[1].isdigit():
            fields = fields[2:4]  # QGroundControl: sysid compid name value type
        if len(fields) != 2:
            raise GcsError(f"line {number}: expected `NAME VALUE`, got {raw!r}")
        try:
            out.append((fields[0], float(fields[1])))
        except ValueError:
            raise GcsError(f"line {number}: {fields[1]!r} is not a number") from None
    return out


def connect(args):
    if args.plant:
        plant = Plant(args.instance, args.wall_limit)
        plant.hello(args.heartbeat_timeout)
        return plant, Params(plant, plant.component)
    vehicle = Vehicle.from_args(args)
    return vehicle, Params(vehicle, AUTOPILOT_COMPONENT)


def run(args):
    link, params = connect(args)
    if args.action == "dump":
        values = params.fetch_all()
        lines = [f"{name:<16} {format_value(value)}" for name, value in values.items()]
        header = f"# {len(values)} parameters of {link.name()} system {link.system_id}"
        text = "\n".join([header, *lines]) + "\n"
        if args.file == "-":
            sys.stdout.write(text)
        else:
            with open(args.file, "w") as f:
                f.write(text)
            print(f"{len(values)} parameters written to {args.file}")
        return 0
    if args.action == "get":
        value, reason = params.read(args.name)
        if value is None:
            raise CheckFailed(f"{args.name}: {reason or 'no answer'} ({link.name()} system {link.system_id})")
        print(f"{args.name} {format_value(value)}")
        return 0
    if args.action == "set":
        echoed, texts = params.set(args.name, args.value)
        return report([(args.name, args.value, echoed, texts)])
    with open(args.file) as f:
        wanted = parse_file(f.read())
    params.fetch_all()  # every parameter's type, to set each in its own
    results = []
    for name, value in wanted:
        echoed, texts = params.set(name, value)
        results.append((name, value, echoed, texts))
    return report(results, verbose=False)


def report(results, verbose=True):
    refused = 0
    for name, value, echoed, texts in results:
        ok = echoed is not None and same_float32(echoed, value)
        why = "; ".join(texts)
        if ok:
            if verbose:
                print(f"{name} {format_value(echoed)}")
            continue
        refused += 1
        if echoed is None:
            print(f"refused: {name} = {format_value(value)}: no PARAM_VALUE echo" + (f" ({why})" if why else ""))
        else:
            print(
                f"refused: {name} = {format_value(value)}: still {format_value(echoed)}" + (f" ({why})" if why else "")
            )
    if not verbose:
        print(f"{len(results) - refused} of {len(results)} parameters set, {refused} refused")
    return 1 if refused else 0


def main(argv=None):
    p = parser()
    return run_main(run, p.parse_args(argv), p.prog)


if __name__ == "__main__":
    sys.exit(main())
