"""Emulated scanner hardware for tests and for trying the app without hardware (docs/devices.md#emulators).

- :mod:`scanner.acquisition.emulators.daq_grpc`: an NI gRPC Device Server for the DAQ, served in process to the real
  ``nidaqmx`` client (``texplorer emulate daq``).
- :mod:`scanner.acquisition.emulators.board`: the serial sensor board on a pseudo-terminal, with injectable faults
  (``texplorer emulate board``). POSIX only: pseudo-terminals do not exist on Windows.

Both play a :class:`~scanner.acquisition.devices.sources.SignalSource`: a simulated material sample or a stored scan.
"""
