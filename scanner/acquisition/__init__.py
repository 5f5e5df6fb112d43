"""Acquiring a scan: the configuration, the devices, their emulators, the recorder and the guided session.

=====================  ===================================================================================
module                 holds
=====================  ===================================================================================
:mod:`.config`         the scanner's configuration: which implementation of each device, channel map,
                       calibration, step durations (one TOML file)
:mod:`.devices`        the devices' interfaces and their real, simulated and replay implementations
:mod:`.emulators`      emulators that play a simulated sample to the real client libraries
:mod:`.recorder`       recording the procedure's steps from the devices and assembling a scan
:mod:`.session`        the guided scanning session, a state machine the CLI and the web page drive
=====================  ===================================================================================

The simulated sensors the simulated devices play are :mod:`scanner.simulation`, beside this package.
"""
