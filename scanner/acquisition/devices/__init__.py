"""Scanner devices (docs/devices.md): the interfaces (:mod:`~scanner.acquisition.devices.protocols`) and, per device, a
real, a simulated and a replay implementation, chosen by the configuration (:mod:`scanner.acquisition.config`).

======================  ========================  ==============================  =========================
device                  real                      simulated                       replay
======================  ========================  ==============================  =========================
DAQ                     ``NidaqmxDaq`` (local or  ``PlaybackDaq`` of a            ``PlaybackDaq`` of a
                        ``grpc://`` server)       ``SimulatedSample``             ``ReplayedScan``
sensor board            ``SerialBoard``           ``PlaybackBoard``               ``PlaybackBoard``
microphone              ``SoundDeviceMicrophone``  ``PlaybackMicrophone``          ``PlaybackMicrophone``
camera                  ``OpenCvCamera``          ``PlaybackCamera``              ``PlaybackCamera``
Peltier                 ``BoardPeltier`` (relay) or ``DaqPeltier`` (digital line), on whichever is configured
======================  ========================  ==============================  =========================

:func:`open_devices` builds the set; :meth:`Devices.close` switches the Peltier off first, then releases
every device, whatever fails on the way.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from scanner.acquisition.config import Config, ConfigError
from scanner.acquisition.devices.audio import PlaybackMicrophone, SoundDeviceMicrophone
from scanner.acquisition.devices.board import BoardPeltier, PlaybackBoard, SerialBoard
from scanner.acquisition.devices.camera import OpenCvCamera, PlaybackCamera
from scanner.acquisition.devices.daq import DaqPeltier, NidaqmxDaq, PlaybackDaq
from scanner.acquisition.devices.protocols import (
    AcquisitionError,
    BoardTimeout,
    Camera,
    ConnectionLost,
    Daq,
    DeviceError,
    DeviceUnavailable,
    Microphone,
    Peltier,
    SensorBoard,
)
from scanner.acquisition.devices.sources import ReplayedScan, SignalSource, Specimen, simulated_sample
from scanner.pacing import Pacer

__all__ = [
    "AcquisitionError", "BoardTimeout", "ConnectionLost", "DeviceError", "DeviceUnavailable", "Devices",
    "open_devices",
]


@dataclass
class Devices:
    """One open set of scanner devices."""

    daq: Daq
    board: SensorBoard
    microphone: Microphone
    camera: Camera
    peltier: Peltier

    def describe(self) -> dict[str, str]:
        """Device names and serials for ``meta.device``."""
        out: dict[str, str] = {}
        for device in (self.daq, self.board, self.microphone, self.camera):
            out.update(device.describe())
        return out

    def close(self) -> None:
        """Peltier off, then close every device; the first failure is raised after all were tried."""
        errors: list[BaseException] = []
        for action in (self.peltier.off, self.daq.close, self.board.close, self.microphone.close,
                       self.camera.close):
            try:
                action()
            except Exception as exc:  # noqa: BLE001 - keep closing the others, report the first
                errors.append(exc)
        if errors:
            raise errors[0]


def open_devices(config: Config, simulated: SignalSource | None = None, *,
                 specimen: Specimen | None = None) -> Devices:
    """Open the devices ``config`` asks for.

    Simulated devices observe ``simulated``, else the simulated sample of ``specimen`` (the sample being
    scanned) that ``config.simulated`` describes; replay devices play ``config.replay.scan``. Devices
    opened before a failure are closed again.

    Raises
    ------
    DeviceUnavailable
        A real device, its driver or its library is missing (one line saying which).
    """
    opened: list[Any] = []
    try:
        sources = _sources(config, simulated, specimen)
        pacers = {kind: Pacer(speed) for kind, speed in
                  (("simulated", 1.0 if config.simulated.realtime else 0.0), ("replay", config.replay.speed))}
        daq = _open(opened, _daq, config, sources, pacers)
        microphone = _open(opened, _microphone, config, sources, pacers)
        board = _open(opened, _board, config, sources, pacers)
        camera = _open(opened, _camera, config, sources, pacers)
    except BaseException:
        for device in reversed(opened):
            device.close()
        raise
    peltier = _peltier(config, daq, board)
    return Devices(daq=daq, board=board, microphone=microphone, camera=camera, peltier=peltier)


def _sources(config: Config, simulated: SignalSource | None,
             specimen: Specimen | None) -> dict[str, SignalSource]:
    choices = set(config.devices.values())
    sources: dict[str, SignalSource] = {}
    if "simulated" in choices:
        if simulated is None and specimen is None:
            raise ConfigError("simulated devices need a simulated sample or the specimen they observe")
        sources["simulated"] = simulated if simulated is not None else simulated_sample(config, specimen)
    if "replay" in choices:
        sources["replay"] = ReplayedScan.load(config.replay.scan)
    return sources


def _open(opened: list[Any], factory: Any, config: Config, sources: dict[str, SignalSource],
          pacers: dict[str, Pacer]) -> Any:
    device = factory(config, sources, pacers)
    opened.append(device)
    return device


def _daq(config: Config, sources: dict[str, SignalSource], pacers: dict[str, Pacer]) -> Daq:
    kind = config.implementation("daq")
    if kind == "nidaqmx":
        return NidaqmxDaq(config.daq)
    return PlaybackDaq(sources[kind], config.calibration, rate=config.daq.rate_hz, block=config.daq.block,
                       pacer=pacers[kind])


def _microphone(config: Config, sources: dict[str, SignalSource], pacers: dict[str, Pacer]) -> Microphone:
    kind = config.implementation("microphone")
    if kind == "sounddevice":
        return SoundDeviceMicrophone(config.microphone)
    # On the DAQ's clock, the microphone records exactly as long as the DAQ was read, even at speed 0; next
    # to another kind of DAQ (a real one) only a real-time clock keeps them together.
    daq_kind = config.implementation("daq")
    pacer = pacers[kind] if daq_kind == kind else Pacer(1.0)
    return PlaybackMicrophone(sources[kind], rate=config.microphone.rate_hz, pacer=pacer)


def _board(config: Config, sources: dict[str, SignalSource], pacers: dict[str, Pacer]) -> SensorBoard:
    kind = config.implementation("board")
    if kind == "serial":
        return SerialBoard(config.board)
    return PlaybackBoard(sources[kind], pacer=Pacer(pacers[kind].speed))


def _camera(config: Config, sources: dict[str, SignalSource], pacers: dict[str, Pacer]) -> Camera:
    kind = config.implementation("camera")
    if kind == "opencv":
        return OpenCvCamera(config.camera)
    return PlaybackCamera(sources[kind])


def _peltier(config: Config, daq: Daq, board: SensorBoard) -> Peltier:
    if config.implementation("peltier") == "daq":
        return DaqPeltier(daq)
    return BoardPeltier(board)
