"""``flexvox devices``: list the rig devices this machine can see, and why others cannot be seen."""

from __future__ import annotations

import json
import os
from pathlib import Path

from app.cli.errors import EXIT_OK

HELP = "list projectors, cameras, serial ports and the simulated rig this machine can reach"

GENTL_ENV = "GENICAM_GENTL64_PATH"


def register(sub) -> None:
    """Add the ``devices`` subcommand."""
    p = sub.add_parser(
        "devices",
        help=HELP,
        description=(
            "List what flexvox can drive from this machine: DLP LightCrafter 4500 projectors on "
            "USB, serial ports (sync boxes), GenTL producers (GenICam cameras) and the simulated "
            "rig, which is always available. For what it cannot reach it says why. Exits 0 "
            "whether or not hardware is found."
        ),
    )
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    p.set_defaults(func=run)


def _projectors(list_usb=None) -> dict:
    from rig_drivers.dlpc350.transport import list_dlpc350
    from rig_drivers.errors import DeviceError

    try:
        found = list_dlpc350(list_usb)
    except DeviceError as exc:
        return {"available": False, "devices": [], "reason": str(exc)}
    if not found:
        return {"available": False, "devices": [],
                "reason": "no DLP LightCrafter 4500 (USB 0451:6401) connected"}
    return {"available": True, "devices": found, "reason": None}


def _serial_ports(comports=None) -> dict:
    if comports is None:
        try:
            from serial.tools.list_ports import comports
        except ImportError as exc:  # pragma: no cover - pyserial is a dependency
            return {"available": False, "devices": [], "reason": f"pyserial is not installed ({exc})"}
    ports = [{"port": info.device, "description": info.description or "",
              "vid_pid": (f"{info.vid:04x}:{info.pid:04x}" if info.vid is not None else None)}
             for info in comports()]
    if not ports:
        return {"available": False, "devices": [], "reason": "no serial ports found"}
    return {"available": True, "devices": ports, "reason": None}


def _gentl_producers(environ=None) -> dict:
    environ = os.environ if environ is None else environ
    value = environ.get(GENTL_ENV, "")
    if not value:
        return {"available": False, "devices": [],
                "reason": f"{GENTL_ENV} is not set: install your camera vendor's GenTL producer "
                          f"(or `pip install genicam` for the simulated one) and set it"}
    files, missing = [], []
    for folder in filter(None, value.split(os.pathsep)):
        path = Path(folder)
        if path.is_file() and path.suffix.lower() == ".cti":
            files.append(str(path))
        elif path.is_dir():
            files.extend(sorted(str(f) for f in path.glob("*.cti")))
        else:
            missing.append(folder)
    reason = None
    if not files:
        reason = f"no .cti files in {GENTL_ENV} ({value})"
    elif missing:
        reason = f"not found: {', '.join(missing)}"
    return {"available": bool(files), "devices": [{"producer": f} for f in files], "reason": reason}


def _simulated(sim_producer=None) -> dict:
    """The simulated rig (always there), and the genicam wheel's simulated GenTL producer."""
    if sim_producer is None:
        from rig_drivers.genicam import simulated_producer as sim_producer
    devices = [{"name": "simulated projector"}, {"name": "simulated camera"}, {"name": "simulated sync box"}]
    viky = sim_producer()
    if viky is not None:
        devices.append({"name": "simulated GenICam camera (genicam wheel)", "producer": str(viky)})
    return {"available": True, "reason": None, "devices": devices}


def survey(*, list_usb=None, comports=None, environ=None, sim_producer=None) -> dict:
    """What this machine can reach, as a JSON-ready dict (injectable probes for tests)."""
    found = {
        "projectors": _projectors(list_usb),
        "serial_ports": _serial_ports(comports),
        "gentl_producers": _gentl_producers(environ),
        "simulated": _simulated(sim_producer),
    }
    # Built-in UARTs (/dev/ttyS*, no USB ids) are listed but do not count as rig hardware.
    usb_serial = any(d["vid_pid"] for d in found["serial_ports"]["devices"])
    found["hardware_found"] = usb_serial or found["projectors"]["available"] \
        or found["gentl_producers"]["available"]
    return found


_TITLES = {"projectors": "DLP LightCrafter 4500 (USB)", "serial_ports": "serial ports (sync box)",
           "gentl_producers": "GenTL producers (GenICam cameras)", "simulated": "simulated rig"}


def _describe(entry: dict) -> str:
    return ", ".join(f"{k} {v}" for k, v in entry.items() if v not in (None, ""))


def run(args, *, probes: dict | None = None) -> int:
    """Carry out ``flexvox devices``."""
    found = survey(**(probes or {}))
    if args.json:
        print(json.dumps(found))
        return EXIT_OK
    for key, title in _TITLES.items():
        section = found[key]
        print(f"{title}:")
        for entry in section["devices"]:
            print(f"  - {_describe(entry)}")
        if section["reason"]:
            print(f"  ({section['reason']})")
    if not found["hardware_found"]:
        print("no rig hardware found on this machine; the simulated rig is available (--rig mock)")
    print("pick a rig with --rig mock (the default) or --rig FILE.toml (see rig_drivers/PROFILES.md)")
    return EXIT_OK
