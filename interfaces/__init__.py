"""Protocol interfaces shared by the daemon and the plant emulator.

Each protocol subpackage has a pure *codec* (bytes/frames ⇄ the typed messages of
:mod:`interfaces.messages`) and a *transport* (pyserial, python-can, pymavlink, zenoh) with a
loopback twin for tests.
"""
