"""The controller's service shell: the daemon's loop on the real clock, its transport readers, state persistence,
the hot-standby replica and deadline spinning — threads, devices, files and Zenoh around the per-step logic of
:mod:`dpcontrol.runtime` (which has none of them)."""
