"""Reading the YAML files the tools are given: vessel configurations and scenarios.

Every way such a file can be wrong — missing, a directory, unreadable, not UTF-8 text (a binary picked by
mistake, a file saved as Latin-1), not YAML — is reported as a :class:`ConfigError` that names the file,
so that ``dpcontrol check-config``, ``dpcontrol run``, ``sim-plant run``/``hil``/``demo`` print one clear
line instead of a traceback.
"""

from __future__ import annotations

import re
from pathlib import Path

import yaml

from dpbase.schema import ConfigError


class Yaml12NumbersLoader(yaml.SafeLoader):
    """PyYAML's safe loader with the floats of YAML 1.2's core schema.

    PyYAML implements YAML 1.1, whose float pattern needs a dot in the mantissa and a sign in the exponent:
    ``6.0e6`` and ``1e-3`` are numbers there, but ``6e6`` and ``6.0e6`` written as ``6E6`` or ``1e3`` are
    *strings*, and a configuration that writes a mass matrix as ``[[6e6, ...]]`` was refused as "expected a
    number". YAML 1.2 (and every other YAML reader a user may check the file with) reads them as floats.
    Only the float resolver changes; booleans, integers and the rest stay PyYAML's (no ruamel.yaml
    dependency for one regular expression).
    """


_YAML12_FLOAT = re.compile(
    r"""^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""",
    re.VERBOSE,
)
# The resolvers are kept per first character; copy the table so that yaml.SafeLoader itself is unchanged.
Yaml12NumbersLoader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag != "tag:yaml.org,2002:float"]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
for _first in "-+.0123456789":
    # after the int resolver: "12" stays an int, "12.0", "1e3" and "6.0e6" become floats
    Yaml12NumbersLoader.yaml_implicit_resolvers.setdefault(_first, []).append(
        ("tag:yaml.org,2002:float", _YAML12_FLOAT))


def load_yaml(text: str) -> object:
    """Parse YAML text with :class:`Yaml12NumbersLoader` (safe: plain data only).

    Raises
    ------
    yaml.YAMLError
        The text is not valid YAML.
    """
    return yaml.load(text, Loader=Yaml12NumbersLoader)


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
        return text, load_yaml(text)
    except yaml.YAMLError as error:
        raise ConfigError("", "valid YAML", str(error).replace("\n", " "), file=file) from None
