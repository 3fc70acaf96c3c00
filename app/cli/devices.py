"""``flexvox devices``: list the rig devices this machine can see, and why others cannot be seen."""

from __future__ import annotations

import json
import os
from pathlib import Path

from flexvox_app.cli.errors import EXIT_OK

HELP = "list projectors, cameras, serial ports, the simulated rig and the GPUs this machine can reach"

GENTL_ENV = "GENICAM_GENTL64_PATH"


def register(sub) -> None:
    """Add the ``devices`` subcommand."""
    p = sub.add_parser(
        "devices",
        help=HELP,
        description=(
            "List what flexvox can drive from this machine: DLP LightCrafter 4500 projectors on "
            "USB, serial ports (sync boxes), GenTL producers (GenICam cameras), the simulated "
            "rig, which is always available, and the NVIDIA GPUs reconstructions can run on (name, memory, "
            "driver). For what it cannot reach it says why. Exits 0 "
            "whether or not hardware is found."
        ),
    )
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    p.set_defaults(func=run)


def _default_projector():
    from rig_drivers.dlpc350 import DLPC350, PyUsbHidTransport

    return DLPC350(PyUsbHidTransport())


def projector_settings(make_projector) -> dict:
    """Open a LightCrafter, read what an operator checks (firmware, power, input source, LED currents
    and enables, errors) and close it; ``{"error": why}`` when it cannot be read."""
    from rig_drivers.errors import DeviceError

    try:
        with make_projector() as lcr:
            return lcr.summary()
    except DeviceError as exc:
        return {"error": str(exc)}


def _projectors(list_usb=None, open_projector=None) -> dict:
    from rig_drivers.dlpc350.transport import list_dlpc350
    from rig_drivers.errors import DeviceError

    try:
        found = list_dlpc350(list_usb)
    except DeviceError as exc:
        return {"available": False, "devices": [], "reason": str(exc)}
    if not found:
        return {"available": False, "devices": [],
                "reason": "no DLP LightCrafter 4500 (USB 0451:6401) connected"}
    if len(found) == 1:  # several: a rig profile's `serial` picks one (flexvox devices --rig FILE.toml)
        found[0]["settings"] = projector_settings(open_projector or _default_projector)
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


def _gpus(describe=None) -> dict:
    """The NVIDIA GPUs reconstructions can run on (``--device cuda``), or why none can be used."""
    from flexvox_core.gpu.device import cuda_status, describe_gpus, simulator

    ok, reason = cuda_status()
    if not ok:
        return {"available": False, "devices": [], "reason": reason}
    if simulator():
        return {"available": False, "devices": [], "reason": f"{reason}: kernels run as Python, for tests"}
    gpus = (describe or describe_gpus)()
    devices = [{"name": g.name, "memory": f"{g.memory_total / 2**30:.1f} GiB",
                "compute_capability": ".".join(map(str, g.compute_capability)), "driver": g.driver} for g in gpus]
    return {"available": bool(devices), "devices": devices, "reason": None if devices else "the driver lists no GPU"}


def survey(*, list_usb=None, comports=None, environ=None, sim_producer=None, open_projector=None,
           describe_gpus=None) -> dict:
    """What this machine can reach, as a JSON-ready dict (injectable probes for tests)."""
    found = {
        "projectors": _projectors(list_usb, open_projector),
        "serial_ports": _serial_ports(comports),
        "gentl_producers": _gentl_producers(environ),
        "simulated": _simulated(sim_producer),
        "gpus": _gpus(describe_gpus),
    }
    # Built-in UARTs (/dev/ttyS*, no USB ids) are listed but do not count as rig hardware.
    usb_serial = any(d["vid_pid"] for d in found["serial_ports"]["devices"])
    found["hardware_found"] = usb_serial or found["projectors"]["available"] \
        or found["gentl_producers"]["available"]
    return found


_TITLES = {"projectors": "DLP LightCrafter 4500 (USB)", "serial_ports": "serial ports (sync box)",
           "gentl_producers": "GenTL producers (GenICam cameras)", "simulated": "simulated rig",
           "gpus": "GPUs for reconstruction (--device cuda)"}


def _describe(entry: dict) -> str:
    return ", ".join(f"{k} {v}" for k, v in entry.items() if v not in (None, "") and k != "settings")


def settings_lines(settings: dict) -> list[str]:
    """A LightCrafter's settings (:func:`projector_settings`) as indented lines."""
    if "error" in settings:
        return [f"    cannot read its settings: {settings['error']}"]
    cur, en = settings["led_current"], settings["led_enable"]
    leds = "driven by the pattern sequence" if en["automatic"] else \
        "on: " + (", ".join(c for c in ("red", "green", "blue") if en[c]) or "none")
    return [f"    firmware {settings['firmware']}, {settings['power']}, input {settings['input_source']}",
            f"    LED current (PWM 0..255): red {cur['red']}, green {cur['green']}, blue {cur['blue']}; LEDs {leds}",
            "    errors: " + ("; ".join(settings["errors"]) or "none")]


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
            if "settings" in entry:
                print("\n".join(settings_lines(entry["settings"])))
        if section["reason"]:
            print(f"  ({section['reason']})")
    if not found["hardware_found"]:
        print("no rig hardware found on this machine; the simulated rig is available (--rig mock)")
    print("pick a rig with --rig mock (the default) or --rig FILE.toml (see rig_drivers/PROFILES.md)")
    return EXIT_OK
