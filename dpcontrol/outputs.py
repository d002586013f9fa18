"""Output folders of the command-line tools, checked before the work that fills them.

A 12 h lockstep run, a demo, or the replay of a day's recording must not end in a traceback, its results
lost, because the folder named on its command line cannot be written: the commands check it first
(``sim-plant run --out``, ``sim-plant demo --out``, ``dpcontrol replay --out``, and the folder of
``dpcontrol run --stats-out``).
"""

from __future__ import annotations

import tempfile
from pathlib import Path


def unwritable_folder(path: Path) -> str | None:
    """Create ``path`` (with its parents) if missing; None when a file can be written into it, else why not.

    Parameters
    ----------
    path : Path
        The output folder.

    Returns
    -------
    str or None
        ``"cannot write into the output folder <path>: <reason>"``, or None.
    """
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=path):  # what the writes will need (permissions, a read-only mount)
            pass
    except OSError as error:
        return f"cannot write into the output folder {path}: {error.strerror or error}"
    return None
