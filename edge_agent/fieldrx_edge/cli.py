"""``fieldrx-edge``: pull jobs, run one, simulate one, replay a receiver log, NDVI mode.

    fieldrx-edge pull --server URL --token DEVICE_TOKEN [--state-dir D]
    fieldrx-edge run JOB_ID --source serial:/dev/ttyACM0@115200 [--motor serial:/dev/ttyUSB0]
    fieldrx-edge run JOB_ID --source file:drive.nmea --replay-speed 10 --offline
    fieldrx-edge run JOB_ID --source tcp:192.168.1.5:2101 --mqtt 127.0.0.1:1884
    fieldrx-edge simulate JOB.json|demo:35x23|demo:20ha --speed 3-9km/h --gnss-noise 0.02 \
        --controller ladrc --lag-compensation on [--seed N] [--server URL --token T] --json
    fieldrx-edge run JOB_ID --source ... --implement isobus --can socketcan:can0
    fieldrx-edge ecu --can pcan:PCAN_USBBUS1 [--job JOB_ID|FILE] [--motor serial:/dev/ttyUSB0]
    fieldrx-edge simulate demo:35x23 --implement isobus      (TC -> virtual CAN -> rate ECU)
    fieldrx-edge replay-nmea LOG [--json]
    fieldrx-edge ndvi file:ndvi.csv [--gnss SRC | --speed-kmh 6] [--machine-id N] [--json]
    fieldrx-edge run JOB_ID --source ... --cab 8088      (the cab display, fieldrx_edge.cab)

Argument parsing only: each command is in ``fieldrx_edge.commands``, and every command
that works a job drives one ``fieldrx_edge.session.JobSession``.

State (cached jobs, progress, telemetry queue) lives in --state-dir, default
$FIELDRX_EDGE_HOME or ~/.fieldrx-edge. After ``pull`` the agent needs no network.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Callable

from fieldrx_edge.protocol import UPLINK_PROFILES, UPLOAD_PERIOD_S

UPLINK_HELP = (
    "telemetry profile: full (every fix) or thin (1 Hz track + one record per cell left; the"
    " 10 Hz log stays in the state dir, `upload-log` sends it). Default: the config's"
    ' "uplink" (set by `pull --uplink`), else full'
)

UPLOAD_PERIOD_HELP = (
    "seconds between uploads of a batch that is not full (a backlog is sent at once)."
    " Default: the uplink profile's, " + ", ".join(f"{k} {v:g}" for k, v in UPLOAD_PERIOD_S.items())
)


def _on_off(v: str) -> bool:
    if v.lower() in ("on", "true", "1", "yes"):
        return True
    if v.lower() in ("off", "false", "0", "no"):
        return False
    raise argparse.ArgumentTypeError("expected on or off")


def _speed_range(v: str) -> tuple[float, float]:
    """'3-9km/h', '3-9', '6km/h' -> (lo, hi) km/h."""
    s = v.lower().replace("km/h", "").replace("kmh", "").strip()
    lo, _, hi = s.partition("-")
    a = float(lo)
    b = float(hi) if hi else a
    if not 0 < a <= b:
        raise argparse.ArgumentTypeError(f"bad speed range {v!r}")
    return a, b


def _address(v: str) -> int:
    """A source address, decimal or 0x.., 0..253 (254 and 255 are NULL and global)."""
    try:
        n = int(v, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"bad address {v!r}") from None
    if not 0 <= n <= 253:
        raise argparse.ArgumentTypeError(f"address {v!r} outside 0..253")
    return n


def _command(name: str) -> Callable[[argparse.Namespace], int]:
    """``module:function`` of ``fieldrx_edge.commands``, imported when the command runs
    (``--help`` and argument errors stay fast)."""
    mod, _, fn = name.partition(":")

    def run(a: argparse.Namespace) -> int:
        return int(getattr(importlib.import_module(f"fieldrx_edge.commands.{mod}"), fn)(a) or 0)

    return run


CAN_HELP = (
    "socketcan:can0, pcan:PCAN_USBBUS1, slcan:/dev/ttyACM0@500000, "
    "socketcand:HOST:PORT:CHANNEL, virtual:NAME (any python-can interface:channel)"
)


def _isobus_args(sp: argparse.ArgumentParser) -> None:
    sp.add_argument(
        "--implement",
        choices=("motor", "isobus"),
        default="motor",
        help="motor: --motor drives the meter; isobus: act as Task Controller on --can",
    )
    sp.add_argument("--can", help=CAN_HELP)
    sp.add_argument("--can-bitrate", type=int, default=250_000, help="ISOBUS: 250000")


def _cab_args(sp: argparse.ArgumentParser) -> None:
    sp.add_argument(
        "--cab",
        metavar="[HOST:]PORT",
        help="serve the operator's cab display here (127.0.0.1 unless a host is given;"
        " any other host needs the pairing token)",
    )
    sp.add_argument(
        "--cab-token", help="pairing token beyond localhost (default: a random one, printed)"
    )
    sp.add_argument(
        "--cab-backlog-alarm", type=int, default=3000, help="queued records that raise an alarm"
    )
    sp.add_argument(
        "--cab-linger", type=float, default=0.0,
        help="after the job: keep the summary on the screen this long (s) or until Close",
    )  # fmt: skip
    sp.add_argument(
        "--cab-wait-start", action="store_true", help="the job starts when Start is pressed"
    )


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="fieldrx-edge",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("-v", "--log-level", default="WARNING")
    sub = p.add_subparsers(dest="cmd", required=True)

    sp = sub.add_parser("pull", help="download this machine's jobs (device token)")
    sp.add_argument("--server")
    sp.add_argument("--token")
    sp.add_argument("--uplink", choices=UPLINK_PROFILES, help="save the default uplink profile")
    sp.add_argument("--state-dir")
    sp.set_defaults(func=_command("run:cmd_pull"))

    sp = sub.add_parser("run", help="run a cached job from a GNSS source")
    sp.add_argument("job", help="cached job id, package file, or demo:35x23")
    sp.add_argument("--state-dir")
    sp.add_argument(
        "--source",
        default="serial:/dev/ttyACM0",
        help="file:LOG, serial:DEV[@baud], tcp:HOST:PORT, udp:PORT",
    )
    sp.add_argument(
        "--replay-speed",
        type=float,
        default=1.0,
        help="file sources: 1 = recorded pace, 0 = as fast as possible",
    )
    sp.add_argument("--server")
    sp.add_argument("--token")
    sp.add_argument(
        "--mqtt",
        help="HOST:PORT: send telemetry over MQTT instead of HTTP"
        " (user machine-ID, password: the device token)",
    )
    sp.add_argument("--mqtt-ca", help="CA certificate file: connect to the broker over TLS")
    sp.add_argument("--offline", action="store_true", help="queue telemetry only")
    sp.add_argument("--uplink", choices=UPLINK_PROFILES, help=UPLINK_HELP)
    sp.add_argument("--upload-period", type=float, help=UPLOAD_PERIOD_HELP)
    sp.add_argument("--motor", default="sim", help="sim or serial:DEV")
    sp.add_argument("--controller")
    sp.add_argument("--lag-compensation", type=_on_off, default=True)
    sp.add_argument("--response-s", type=float, help="motor response added to the look-ahead")
    sp.add_argument("--drain-timeout", type=float, default=30.0)
    sp.add_argument("--early-start", action="store_true", help="anticipate shaft spin-up")
    sp.add_argument("--min-fix-quality", type=int, default=1, help="GGA quality (4 = RTK fixed)")
    sp.add_argument("--max-hdop", type=float, default=5.0, help="0 disables the HDOP check")
    _isobus_args(sp)
    sp.add_argument("--tc-address", type=_address, default=0xF7, help="preferred TC source address")
    sp.add_argument(
        "--density",
        type=float,
        help="kg/l, only for job packages without the product's density: lets volume-rate"
        " implements (DDI 1) take a kg/ha job",
    )
    sp.add_argument("--sensor", help="sensor jobs: NDVI / depth sensor source (serial: or file:)")
    _cab_args(sp)
    sp.set_defaults(func=_command("run:cmd_run"))

    sp = sub.add_parser("ecu", help="rate ECU: the motor loop as an ISOBUS TC client")
    sp.add_argument("--can", required=True, help=CAN_HELP)
    sp.add_argument("--can-bitrate", type=int, default=250_000)
    sp.add_argument("--job", help="job (id or file) for calibration, width and controller")
    sp.add_argument("--state-dir")
    sp.add_argument("--width", type=float, help="working width m (default: the job's, else 2.3)")
    sp.add_argument("--sections", type=int, default=1)
    sp.add_argument("--motor", default="sim", help="sim or serial:DEV")
    sp.add_argument("--controller")
    sp.add_argument("--address", type=_address, default=0x80, help="preferred source address")
    sp.add_argument("--identity", type=int, default=0x2A2, help="NAME identity number")
    sp.add_argument("--duration", type=float, default=0.0, help="stop after S seconds (0: never)")
    sp.set_defaults(func=_command("run:cmd_ecu"))

    sp = sub.add_parser("simulate", help="drive a job in simulation")
    sp.add_argument("job", help="package file, or demo:35x23 / demo:20ha")
    sp.add_argument("--speed", type=_speed_range, default=(3.0, 9.0))
    sp.add_argument("--gnss-noise", type=float, default=0.02, help="position noise, m (1 sigma)")
    sp.add_argument("--speed-noise", type=float, default=0.064, help="speed noise, m/s (1 sigma)")
    sp.add_argument("--gnss-hz", type=float, default=10.0)
    sp.add_argument("--controller")
    sp.add_argument("--lag-compensation", type=_on_off, default=True)
    sp.add_argument("--seed", type=int, default=0)
    sp.add_argument(
        "--compare-runs", type=int, default=20, help="swaths re-driven without compensation"
    )
    sp.add_argument("--server")
    sp.add_argument("--token")
    sp.add_argument("--state-dir")
    sp.add_argument("--drain-timeout", type=float, default=60.0)
    sp.add_argument("--uplink", choices=UPLINK_PROFILES, default="full", help=UPLINK_HELP)
    sp.add_argument("--upload-period", type=float, help=UPLOAD_PERIOD_HELP)
    sp.add_argument("--realtime", type=float, default=0.0, help="pace: 1 = real time, 10 = 10x")
    sp.add_argument(
        "--sensor-fault", type=float, nargs=2, metavar=("FROM_S", "TO_S"),
        help="sensor jobs: the sensor falls silent between these drive times",
    )  # fmt: skip
    sp.add_argument("--cells-out")
    sp.add_argument("--json", action="store_true")
    sp.add_argument("--verbose", action="store_true")
    sp.add_argument(
        "--implement",
        choices=("direct", "isobus"),
        default="direct",
        help="isobus: the motor sits behind a rate ECU, driven by the TC over a virtual CAN bus",
    )
    sp.add_argument("--sections", type=int, default=1, help="isobus: sections of the rate ECU")
    _cab_args(sp)
    sp.set_defaults(func=_command("simulate:cmd_simulate"))

    sp = sub.add_parser(
        "upload-log", help="upload thin jobs' 10 Hz logs (given, else those requested)"
    )
    sp.add_argument("job", nargs="*", type=int, help="job ids (default: the requested ones)")
    sp.add_argument("--state-dir")
    sp.add_argument("--server")
    sp.add_argument("--token")
    sp.add_argument("--timeout", type=float, default=300.0)
    sp.set_defaults(func=_command("tools:cmd_upload_log"))

    sp = sub.add_parser("replay-nmea", help="parse a receiver log and report")
    sp.add_argument("log")
    sp.add_argument("--speed", type=float, default=0.0, help="0 = as fast as possible")
    sp.add_argument("--json", action="store_true")
    sp.set_defaults(func=_command("tools:cmd_replay"))

    sp = sub.add_parser("ndvi", help="seed 000 NDVI mode on a sensor log or serial port")
    sp.add_argument("source")
    sp.add_argument("--speed-kmh", type=float, default=6.0)
    sp.add_argument("--width", type=float, default=3.6)
    sp.add_argument("--gnss", help="GNSS source for the speed (else --speed-kmh)")
    sp.add_argument("--replay-speed", type=float, default=0.0, help="file sources: 0 = fast")
    sp.add_argument("--controller", default="ladrc")
    sp.add_argument("--machine-id", type=int, help="queue telemetry as this machine")
    sp.add_argument("--state-dir")
    sp.add_argument("--server")
    sp.add_argument("--token")
    sp.add_argument("--mqtt")
    sp.add_argument("--mqtt-ca")
    sp.add_argument("--offline", action="store_true")
    sp.add_argument("--drain-timeout", type=float, default=30.0)
    sp.add_argument("--json", action="store_true")
    sp.set_defaults(func=_command("tools:cmd_ndvi"))
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=getattr(logging, str(args.log_level).upper(), logging.WARNING))
    return int(args.func(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
