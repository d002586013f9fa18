"""Reading the YAML files the tools are given: vessel configurations and scenarios.

Every way such a file can be wrong — missing, a directory, unreadable, not UTF-8 text (a binary picked by
mistake, a file saved as Latin-1), not YAML — is reported as a :class:`ConfigError` that names the file,
so that ``dpcontrol check-config``, ``dpcontrol run``, ``sim-plant run``/``hil``/``demo`` print one clear
line instead of a traceback.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from dpcontrol.models.schema import ConfigError


def read_yaml_file(path: str | Path, *, what: str = "a readable file") -> tuple[str, object]:
    """Read and parse a UTF-8 YAML file.

    Parameters
    ----------
    path : str or Path
        The file.
    what : str
        What the file should have been, for the message of an unreadable one
        (e.g. ``"a readable controller configuration file"``).

    Returns
    -------
    (str, object)
        The text and the parsed document (any YAML value: the caller checks its shape).

    Raises
    ------
    ConfigError
        Naming the file: unreadable, not UTF-8, or invalid YAML (with the line and column).
    """
    file = str(path)
    try:
        raw = Path(path).read_bytes()
    except OSError as error:
        raise ConfigError("", what, str(error), file=file) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise ConfigError("", "UTF-8 text", f"byte 0x{raw[error.start]:02x} at offset {error.start} "
                          "(a binary file, or text in another encoding)", file=file) from None
    try:
        return text, yaml.safe_load(text)
    except yaml.YAMLError as error:
        raise ConfigError("", "valid YAML", str(error).replace("\n", " "), file=file) from None
