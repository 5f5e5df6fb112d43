"""The scanner's configuration: which device implementation to use, device names, channel map, calibration
and step durations (docs/devices.md). One TOML file; every key is optional and defaults to the simulated
scanner, so ``texplorer scan`` runs on a laptop with nothing plugged in.

A documented example with every key is ``docs/texplorer.example.toml``. Loading validates everything and
raises :class:`ConfigError` naming the file and the key (``texplorer.toml: daq.rate_hz: must be > 0``).

The calibration converts DAQ volts to the units of docs/database.md (and back, for the simulated and replay devices,
which produce volts where a real device gives volts):

=================  ====================================================  ==========================
role               volts -> unit                                          default
=================  ====================================================  ==========================
``accel_x/y/z``    ADXL335 ``g = (V - zero) / sensitivity``               1.65 V, 0.330 V/g per axis
``ir``             reflectance stays in volts                             -
``fsr_normal/..``  paper eq. (1) ``f = 9.81 * 0.01 * exp(1.33 V)`` N      fixed by the paper
``flex``           two-point line through (v0, deg0) and (v1, deg1)       (0 V, 0 deg), (1 V, 100 deg)
``metal``          ``+1`` below the threshold (shorted), else ``-1``      2.5 V
=================  ====================================================  ==========================
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from scanner.calibration import (
    ACCEL_V_PER_G,
    ACCEL_ZERO_V,
    accel_g,
    flex_degrees,
    fsr_newtons,
    fsr_volts,
    metal_sign,
)
from scanner.photo import PhotoError, check_size
from scanner.scan import MAX_CHANNEL_SECONDS
from taxonomy.errors import TexplorerError

DAQ_ROLES = ("accel_x", "accel_y", "accel_z", "ir", "fsr_normal", "fsr_tangential", "flex", "metal")
"""What is wired to the DAQ's analog inputs (docs/devices.md)."""

DEFAULT_CHANNEL_MAP: Mapping[str, str] = MappingProxyType(
    {role: f"ai{i}" for i, role in enumerate(DAQ_ROLES)})
"""docs/devices.md: ai0-ai2 accelerometer x/y/z, ai3 IR, ai4 FSR normal, ai5 FSR tangential, ai6 flex, ai7 metal."""

CHANNEL_ROLES: Mapping[str, tuple[str, ...]] = MappingProxyType({
    "v_ft": ("accel_x", "accel_y", "accel_z"), "v_fs": ("accel_x", "accel_y", "accel_z"),
    "v_tt": ("accel_x", "accel_y", "accel_z"), "v_ts": ("accel_x", "accel_y", "accel_z"),
    "r_fs": ("ir",), "r_ts": ("ir",),
    "f_frn": ("fsr_normal",), "f_frt": ("fsr_tangential",), "f_press": ("fsr_normal",),
    "f_fold": ("fsr_normal",), "alpha_f": ("flex",), "m": ("metal",),
})
"""Scan channels recorded on the DAQ and the DAQ roles they are computed from (the step is in CHANNELS)."""

MAX_HEAT_S = 5.0
"""The Peltier element never heats longer than this (docs/devices.md); the board refuses longer HEAT commands."""

MAX_HANDLING_S = 3600.0
"""The longest handling time a step may be given (an hour: a displacement volume of a porous sample)."""

IMPLEMENTATIONS: Mapping[str, tuple[str, ...]] = MappingProxyType({
    "daq": ("simulated", "nidaqmx", "replay"),
    "board": ("simulated", "serial", "replay"),
    "microphone": ("simulated", "sounddevice", "replay"),
    "camera": ("simulated", "opencv", "replay"),
    "peltier": ("board", "daq"),
})
"""Per device, the implementations a config may choose; the first is the default."""

METAL_SHORTED_V = 0.2
METAL_OPEN_V = 4.8
"""Electrode volts a simulated or replayed sample gives when conductive (shorted) and not (pull-up)."""

_GRPC = re.compile(r"^grpc://(?P<address>[^/\s]+:\d{1,5})$")
_AI = re.compile(r"^ai\d{1,3}$")


class ConfigError(TexplorerError, ValueError):
    """The configuration file or a value in it is invalid; the message names the file and the key."""


@dataclass(frozen=True)
class Calibration:
    """Sensor calibration (docs/devices.md): ADXL335 zero and sensitivity per axis, flex two-point line, metal
    threshold. FSR volts follow the fixed paper eq. (1)."""

    accel_zero_v: tuple[float, float, float] = (ACCEL_ZERO_V,) * 3
    accel_v_per_g: tuple[float, float, float] = (ACCEL_V_PER_G,) * 3
    flex_v0: float = 0.0
    flex_deg0: float = 0.0
    flex_v1: float = 1.0
    flex_deg1: float = 100.0
    metal_threshold_v: float = 2.5

    def to_physical(self, role: str, volts: np.ndarray) -> np.ndarray:
        """DAQ volts of one role in the unit of its scan channel (g, V, N, deg, +-1)."""
        if role.startswith("accel_"):
            axis = "xyz".index(role[-1])
            return accel_g(volts, self.accel_zero_v[axis], self.accel_v_per_g[axis])
        if role == "ir":
            return np.asarray(volts, dtype=np.float64)
        if role.startswith("fsr_"):
            return fsr_newtons(volts)
        if role == "flex":
            return flex_degrees(volts, self.flex_v0, self.flex_deg0, self.flex_v1, self.flex_deg1)
        if role == "metal":
            return metal_sign(volts, self.metal_threshold_v)
        raise ConfigError(f"unknown DAQ role {role!r} (known: {', '.join(DAQ_ROLES)})")

    def to_volts(self, role: str, values: np.ndarray) -> np.ndarray:
        """The inverse of :meth:`to_physical`: what the DAQ would have read for these values.

        FSR forces below the eq. (1) floor of 0.0981 N read 0 V; the metal signal maps to the shorted
        (0.2 V) or open (4.8 V) electrode level.
        """
        values = np.asarray(values, dtype=np.float64)
        if role.startswith("accel_"):
            axis = "xyz".index(role[-1])
            return self.accel_zero_v[axis] + self.accel_v_per_g[axis] * values
        if role == "ir":
            return values.copy()
        if role.startswith("fsr_"):
            return fsr_volts(values)
        if role == "flex":
            slope = (self.flex_v1 - self.flex_v0) / (self.flex_deg1 - self.flex_deg0)
            return self.flex_v0 + slope * (values - self.flex_deg0)
        if role == "metal":
            return np.where(values > 0, METAL_SHORTED_V, METAL_OPEN_V)
        raise ConfigError(f"unknown DAQ role {role!r} (known: {', '.join(DAQ_ROLES)})")

    def as_meta(self) -> dict[str, float]:
        """Flat numbers for ``meta.calibration`` of a scan, so the conversion can be redone later."""
        out = {f"accel_zero_V_{a}": v for a, v in zip("xyz", self.accel_zero_v, strict=True)}
        out.update({f"accel_V_per_g_{a}": v for a, v in zip("xyz", self.accel_v_per_g, strict=True)})
        out.update(flex_v0_V=self.flex_v0, flex_deg0=self.flex_deg0, flex_v1_V=self.flex_v1,
                   flex_deg1=self.flex_deg1, metal_threshold_V=self.metal_threshold_v)
        return out


@dataclass(frozen=True)
class StepDurations:
    """Recording length of every step in seconds (docs/operator.md#procedure); ``heat`` is the Peltier time of the
    thermal step (at most 5 s), ``thermal`` the cooling record after it."""

    finger_tap: float = 5.0
    finger_slide: float = 5.0
    tool_tap: float = 5.0
    tool_slide: float = 5.0
    static: float = 1.0
    heat: float = 3.0
    thermal: float = 10.0
    friction: float = 5.0
    press: float = 5.0
    fold: float = 5.0


@dataclass(frozen=True)
class HandlingTimes:
    """Seconds the operator needs for each step besides its recording: placing and steadying the unit,
    mounting the steel tip (tool tap), picking up TU2 (static touch), gripping the edge (fold), the three
    photos with the lens change and flash, weighing, the displacement volume and judging (TU4). The quick scan
    (docs/quick.md) weighs each step's information by its recording plus this time; the defaults are a trained
    operator's, measure your own lab's and set them here."""

    finger_tap: float = 5.0
    finger_slide: float = 5.0
    tool_tap: float = 15.0
    tool_slide: float = 5.0
    static: float = 10.0
    thermal: float = 5.0
    friction: float = 5.0
    press: float = 5.0
    fold: float = 10.0
    photos: float = 60.0
    tu4: float = 120.0


@dataclass(frozen=True)
class DaqConfig:
    """NI-DAQmx device (``nidaqmx``): device name, optional remote gRPC server, rate, read cadence, buffer,
    input range and terminal configuration, the Peltier's digital line and the channel map."""

    device: str = "Dev1"
    server: str = ""
    rate_hz: float = 3000.0
    reads_per_second: float = 15.0
    buffer_s: float = 2.0
    range_v: float = 10.0
    terminal: str = "RSE"
    peltier_line: str = "port0/line0"
    keep_raw: bool = True
    channels: Mapping[str, str] = field(default_factory=lambda: DEFAULT_CHANNEL_MAP)

    @property
    def grpc_address(self) -> str | None:
        """``host:port`` of a remote NI gRPC Device Server, or None for a local device."""
        match = _GRPC.match(self.server)
        return match["address"] if match else None

    @property
    def block(self) -> int:
        """Samples per channel in one read (rate / reads per second)."""
        return max(1, int(round(self.rate_hz / self.reads_per_second)))

    @property
    def physical_channels(self) -> tuple[str, ...]:
        """The analog inputs read, in the order of :data:`DAQ_ROLES`."""
        return tuple(self.channels[role] for role in DAQ_ROLES)


@dataclass(frozen=True)
class BoardConfig:
    """Serial sensor board (``pyserial``): port by name (``COM3``, ``/dev/ttyACM0``), baud rate, silence
    timeout, how long to try reconnecting, stream rates."""

    port: str = "/dev/ttyACM0"
    baudrate: int = 115200
    timeout_s: float = 1.0
    reconnect_s: float = 5.0
    thermal_hz: float = 20.0
    magnet_hz: float = 80.0


@dataclass(frozen=True)
class MicrophoneConfig:
    """Microphone (``sounddevice``): device name or index ("" = system default), rate, block size."""

    device: str = ""
    rate_hz: float = 44100.0
    blocksize: int = 1024


@dataclass(frozen=True)
class CameraConfig:
    """Camera (OpenCV ``VideoCapture``): an index ("0"), a URL or a video file; frames to let exposure
    settle before the one kept."""

    source: str = "0"
    warmup_frames: int = 5


@dataclass(frozen=True)
class SimulatedConfig:
    """The simulated scanner: material slug ("" = the library material with the session's label), seed,
    whether devices run in real time, photo size."""

    material: str = ""
    seed: int = 0
    realtime: bool = True
    image_size: tuple[int, int] = (512, 512)


@dataclass(frozen=True)
class ReplayConfig:
    """Replay devices: the stored scan (``.mat``) they play and the speed (1 = real time, 0 = at once)."""

    scan: str = ""
    speed: float = 1.0


@dataclass(frozen=True)
class Config:
    """The whole configuration; ``devices`` maps daq/board/microphone/camera/peltier to an implementation."""

    devices: Mapping[str, str] = field(default_factory=lambda: MappingProxyType(
        {name: choices[0] for name, choices in IMPLEMENTATIONS.items()}))
    steps: StepDurations = StepDurations()
    handling: HandlingTimes = HandlingTimes()
    daq: DaqConfig = DaqConfig()
    board: BoardConfig = BoardConfig()
    microphone: MicrophoneConfig = MicrophoneConfig()
    camera: CameraConfig = CameraConfig()
    simulated: SimulatedConfig = SimulatedConfig()
    replay: ReplayConfig = ReplayConfig()
    calibration: Calibration = Calibration()
    source: str = "defaults"

    def implementation(self, device: str) -> str:
        """The implementation chosen for ``device`` (daq, board, microphone, camera, peltier)."""
        return self.devices[device]

    def with_devices(self, **choices: str) -> Config:
        """A copy with some device implementations replaced (validated like the file)."""
        devices = {**self.devices, **_devices(self.source, {**self.devices, **choices})}
        config = replace(self, devices=MappingProxyType(devices))
        _check(config)
        return config

    def with_board_port(self, port: str) -> Config:
        """A copy that uses the real sensor board on serial port ``port`` (``COM3``, ``/dev/ttyACM0``)."""
        config = replace(self, board=replace(self.board, port=port),
                         devices=MappingProxyType({**self.devices, "board": "serial"}))
        _check(config)
        return config

    def with_daq_server(self, server: str) -> Config:
        """A copy that reads the real DAQ through a remote NI gRPC Device Server (``grpc://host:port``)."""
        config = replace(self, daq=replace(self.daq, server=server),
                         devices=MappingProxyType({**self.devices, "daq": "nidaqmx"}))
        _check(config)
        return config


def load_config(path: str | Path | None = None) -> Config:
    """Read and validate a TOML config; None gives the defaults (everything simulated).

    Raises
    ------
    ConfigError
        The file cannot be read or parsed, has an unknown section or key, or a value of the wrong type or
        out of range; the message names the file and the key.
    """
    if path is None:
        return Config()
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the config: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
    return parse_config(data, str(path))


_SECTIONS: dict[str, type] = {
    "steps": StepDurations, "handling": HandlingTimes, "daq": DaqConfig, "board": BoardConfig,
    "microphone": MicrophoneConfig,
    "camera": CameraConfig, "simulated": SimulatedConfig, "replay": ReplayConfig, "calibration": Calibration,
}


def parse_config(data: Mapping[str, Any], source: str = "config") -> Config:
    """Validate the parsed TOML tables ``data`` (see :func:`load_config`); ``source`` names them in errors."""
    unknown = set(data) - {"devices", *_SECTIONS}
    if unknown:
        raise ConfigError(f"{source}: unknown section [{sorted(unknown)[0]}] "
                          f"(known: devices, {', '.join(_SECTIONS)})")
    values: dict[str, Any] = {"source": source}
    values["devices"] = MappingProxyType(_devices(source, _table(source, "devices", data.get("devices", {}))))
    for name, cls in _SECTIONS.items():
        values[name] = _section(source, name, cls, _table(source, name, data.get(name, {})))
    config = Config(**values)
    _check(config)
    return config


def _table(source: str, key: str, value: Any) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise ConfigError(f"{source}: {key}: must be a table, got {type(value).__name__}")
    return value


def _choice(source: str, key: str, value: Any, choices: tuple[str, ...]) -> str:
    if value not in choices:
        raise ConfigError(f"{source}: {key}: {value!r} is not one of {', '.join(choices)}")
    return str(value)


def _devices(source: str, table: Mapping[str, Any]) -> dict[str, str]:
    unknown = set(table) - set(IMPLEMENTATIONS)
    if unknown:
        raise ConfigError(f"{source}: devices.{sorted(unknown)[0]}: unknown device "
                          f"(known: {', '.join(IMPLEMENTATIONS)})")
    return {name: _choice(source, f"devices.{name}", table.get(name, choices[0]), choices)
            for name, choices in IMPLEMENTATIONS.items()}


def _section(source: str, name: str, cls: type, table: Mapping[str, Any]) -> Any:
    defaults = cls()
    known = {f.name for f in fields(cls)}
    unknown = set(table) - known
    if unknown:
        raise ConfigError(f"{source}: {name}.{sorted(unknown)[0]}: unknown key "
                          f"(known: {', '.join(sorted(known))})")
    values = {key: _typed(source, f"{name}.{key}", value, getattr(defaults, key))
              for key, value in table.items()}
    return replace(defaults, **values)


def _typed(source: str, key: str, value: Any, default: Any) -> Any:
    """``value`` converted to the type of ``default``, or a ConfigError naming ``key``."""
    where = f"{source}: {key}"
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ConfigError(f"{where}: must be true or false, got {value!r}")
        return value
    if isinstance(default, int):
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where}: must be an integer, got {value!r}")
        return value
    if isinstance(default, float):
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise ConfigError(f"{where}: must be a finite number, got {value!r}")
        return float(value)
    if isinstance(default, str):
        if isinstance(value, int) and not isinstance(value, bool):
            return str(value)
        if not isinstance(value, str):
            raise ConfigError(f"{where}: must be a string, got {value!r}")
        return value
    if isinstance(default, tuple):
        if not isinstance(value, list) or len(value) != len(default):
            raise ConfigError(f"{where}: must be a list of {len(default)} numbers, got {value!r}")
        pairs = enumerate(zip(value, default, strict=True))
        return tuple(_typed(source, f"{key}[{i}]", v, d) for i, (v, d) in pairs)
    if isinstance(default, Mapping):
        return MappingProxyType(_channel_map(where, value))
    raise ConfigError(f"{where}: unsupported value {value!r}")


def _channel_map(where: str, value: Any) -> dict[str, str]:
    if not isinstance(value, Mapping):
        raise ConfigError(f"{where}: must be a table of role = \"aiN\"")
    unknown = set(value) - set(DAQ_ROLES)
    if unknown:
        raise ConfigError(f"{where}.{sorted(unknown)[0]}: unknown role (known: {', '.join(DAQ_ROLES)})")
    channels = {**DEFAULT_CHANNEL_MAP, **value}
    for role, name in channels.items():
        if not isinstance(name, str) or not _AI.match(name):
            raise ConfigError(f"{where}.{role}: {name!r} is not an analog input name like 'ai3'")
    doubled = [name for name in set(channels.values()) if list(channels.values()).count(name) > 1]
    if doubled:
        raise ConfigError(f"{where}: {doubled[0]} is mapped to more than one role")
    return channels


def _positive(source: str, key: str, value: float) -> None:
    if not value > 0:
        raise ConfigError(f"{source}: {key}: must be > 0, got {value!r}")


def _check(config: Config) -> None:
    """Range checks that need more than a type."""
    source = config.source
    for f in fields(StepDurations):
        _positive(source, f"steps.{f.name}", getattr(config.steps, f.name))
        if getattr(config.steps, f.name) > MAX_CHANNEL_SECONDS:
            raise ConfigError(f"{source}: steps.{f.name}: at most {MAX_CHANNEL_SECONDS:g} s, the longest a scan "
                              "channel may hold")
    for f in fields(HandlingTimes):
        value = getattr(config.handling, f.name)
        if not 0 <= value <= MAX_HANDLING_S:
            raise ConfigError(f"{source}: handling.{f.name}: must be between 0 and {MAX_HANDLING_S:g} s, got {value!r}")
    if config.steps.heat > MAX_HEAT_S:
        raise ConfigError(f"{source}: steps.heat: {config.steps.heat:g} s exceeds the "
                          f"{MAX_HEAT_S:g} s Peltier limit")
    daq = config.daq
    for key in ("rate_hz", "reads_per_second", "buffer_s", "range_v"):
        _positive(source, f"daq.{key}", getattr(daq, key))
    if daq.server and daq.grpc_address is None:
        raise ConfigError(f"{source}: daq.server: {daq.server!r} must look like grpc://host:port")
    if daq.terminal not in ("RSE", "NRSE", "DIFF", "DEFAULT"):
        raise ConfigError(f"{source}: daq.terminal: {daq.terminal!r} is not one of RSE, NRSE, DIFF, DEFAULT")
    if daq.buffer_s * daq.rate_hz < 2 * daq.block:
        raise ConfigError(f"{source}: daq.buffer_s: {daq.buffer_s:g} s holds fewer than two reads")
    for key in ("baudrate", "timeout_s", "reconnect_s", "thermal_hz", "magnet_hz"):
        _positive(source, f"board.{key}", getattr(config.board, key))
    if not config.board.port.strip():
        raise ConfigError(f"{source}: board.port: must name a serial port (COM3, /dev/ttyACM0)")
    _positive(source, "microphone.rate_hz", config.microphone.rate_hz)
    _positive(source, "microphone.blocksize", config.microphone.blocksize)
    if config.camera.warmup_frames < 0:
        raise ConfigError(f"{source}: camera.warmup_frames: must be >= 0")
    if min(config.simulated.image_size) < 16:
        raise ConfigError(f"{source}: simulated.image_size: both sides must be >= 16 px")
    try:
        check_size(*config.simulated.image_size[::-1], name="simulated.image_size")
    except PhotoError as problem:
        raise ConfigError(f"{source}: {problem}") from None
    if config.replay.speed < 0:
        raise ConfigError(f"{source}: replay.speed: must be >= 0 (0 = as fast as possible)")
    if "replay" in config.devices.values() and not config.replay.scan:
        raise ConfigError(f"{source}: replay.scan: replay devices need the path of a stored scan")
    calibration = config.calibration
    if min(calibration.accel_v_per_g) <= 0:
        raise ConfigError(f"{source}: calibration.accel_v_per_g: sensitivities must be > 0 V/g")
    if calibration.flex_v0 == calibration.flex_v1 or calibration.flex_deg0 == calibration.flex_deg1:
        raise ConfigError(f"{source}: calibration.flex_*: the two flex points must differ in volts "
                          "and in degrees")
