"""The layer rule of docs/design.md §1, checked on the source: imports point down only.

* the numeric core has no I/O, no clock, no threads, no logging set-up;
* interfaces never import the controller's runtime or algorithms;
* the plant never imports the controller (it may use the shared vessel data in
  ``dpcontrol.models``); only the composition packages ``sim_plant.bench`` and ``sim_plant.campaign`` (and the
  ``sim-plant`` command line) compose plant and controller, and the plant never imports them.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

CORE = ["dpcontrol/models", "dpcontrol/estimation", "dpcontrol/guidance", "dpcontrol/control",
        "dpcontrol/allocation"]
CORE_FORBIDDEN = {"time", "os", "sys", "socket", "threading", "logging", "subprocess", "asyncio", "io",
                  "serial", "can", "zenoh", "pymavlink", "yaml", "datetime", "random", "pathlib",
                  "interfaces", "sim_plant", "dpcontrol.runtime", "dpcontrol.service", "dpcontrol.cli"}
CONTROLLER = {"dpcontrol.estimation", "dpcontrol.guidance", "dpcontrol.control", "dpcontrol.allocation",
              "dpcontrol.runtime", "dpcontrol.service", "dpcontrol.cli"}


def _imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    names: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.extend(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.append(node.module)
    return names


def _violations(files: list[Path], forbidden: set[str]) -> list[str]:
    found = []
    for path in files:
        for name in _imports(path):
            if any(name == bad or name.startswith(bad + ".") for bad in forbidden):
                found.append(f"{path.relative_to(ROOT)} imports {name}")
    return found


def _files(*folders: str) -> list[Path]:
    return sorted(p for folder in folders for p in (ROOT / folder).rglob("*.py"))


@pytest.mark.parametrize("folder", CORE)
def test_core_has_no_io_clock_or_upper_layers(folder: str) -> None:
    assert _violations(_files(folder), CORE_FORBIDDEN) == []


def test_interfaces_do_not_import_the_controller() -> None:
    assert _violations(_files("interfaces"), CONTROLLER | {"sim_plant"}) == []


def test_interfaces_import_nothing_of_dpcontrol() -> None:
    """The shared vocabulary (frames, configuration checks) is in dpbase, below both."""
    assert _violations(_files("interfaces"), {"dpcontrol"}) == []


def test_the_base_package_imports_no_project_package() -> None:
    assert _files("dpbase"), "dpbase has no sources"
    assert _violations(_files("dpbase"), {"dpcontrol", "interfaces", "sim_plant"}) == []


#: What the per-step logic (dpcontrol/runtime) never imports: threads, the clock, devices, the wire, the service shell.
RUNTIME_FORBIDDEN = {"threading", "time", "socket", "subprocess", "asyncio", "os", "signal", "ctypes", "serial", "can",
                     "zenoh", "interfaces.zenoh.node", "interfaces.systemd", "dpcontrol.service", "dpcontrol.cli"}


def test_the_per_step_logic_has_no_threads_clock_devices_or_service_shell() -> None:
    files = _files("dpcontrol/runtime")
    assert files, "dpcontrol/runtime has no sources"
    assert _violations(files, RUNTIME_FORBIDDEN) == []


def test_the_service_shell_is_imported_by_no_lower_layer() -> None:
    lower = _files("dpbase", "interfaces", "sim_plant", "dpcontrol/runtime", *CORE)
    allowed = {p for p in _files("sim_plant/bench")}  # composition: the bench wires plant and controller
    assert _violations([p for p in lower if p not in allowed], {"dpcontrol.service"}) == []


COMPOSITION = ("bench", "campaign")  # sim_plant's packages allowed to import the controller


def _plant_files() -> list[Path]:
    return [p for p in _files("sim_plant") if not set(COMPOSITION) & set(p.relative_to(ROOT).parts)
            and p.name != "cli.py"]


def test_plant_never_imports_the_controller() -> None:
    files = _plant_files()
    assert files, "sim_plant has no sources"
    assert _violations(files, CONTROLLER) == []


def test_operator_tools_speak_only_zenoh() -> None:
    """The console (like the monitor and dpcontrol setpoint) reaches the controller over Zenoh only: it never
    imports the controller's runtime or algorithms (it may use the shared vessel data in dpcontrol.models)."""
    files = [ROOT / "dpcontrol" / name for name in ("console.py", "monitor.py", "setpoint.py")]
    assert _violations(files, CONTROLLER | {"sim_plant"}) == []


def test_plant_never_imports_the_composition_layer() -> None:
    forbidden = {f"sim_plant.{name}" for name in COMPOSITION} | {"sim_plant.cli"}
    assert _violations(_plant_files(), forbidden) == []


def test_the_composition_packages_exist() -> None:
    for name in COMPOSITION:  # (a renamed package would silently leave the plant rule checking nothing of it)
        assert (ROOT / "sim_plant" / name / "__init__.py").exists()


#: What the per-step logic must never load, even indirectly: the wire (Zenoh and its schemas, TLS), the
#: transports, the recorder and the daemon's file parser (which reads transport and Zenoh settings).
SERVICE_MODULES = ("zenoh", "serial", "can", "pymavlink", "cryptography", "interfaces.zenoh", "interfaces.recorder",
                   "interfaces.nmea0183", "interfaces.nmea2000", "interfaces.mavlink", "sim_plant",
                   "dpcontrol.runtime.config", "dpcontrol.service.daemon")


@pytest.mark.parametrize("module", ["dpcontrol.runtime.step", "dpcontrol.runtime.hub"])
def test_the_step_and_the_hub_load_no_transport_wire_or_recorder(module: str) -> None:
    """Checked on the modules Python actually loads (a fresh interpreter), so an indirect import counts too."""
    probe = (f"import sys, {module}\n"
             f"bad = {SERVICE_MODULES!r}\n"
             "print('\\n'.join(sorted(m for m in sys.modules if any(m == b or m.startswith(b + '.') for b in bad))))")
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, cwd=ROOT,
                            check=True)
    assert result.stdout.split() == []


def _module_graph() -> dict[str, set[str]]:
    """Project module → the project modules it imports (at module level or inside functions: a lazy import
    still ties the two); an import of a module's own package (its ``__init__``) is not counted."""
    modules: dict[str, Path] = {}
    for package in ("dpbase", "dpcontrol", "interfaces", "sim_plant"):
        for path in (ROOT / package).rglob("*.py"):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            modules[".".join(parts)] = path

    def resolve(name: str) -> str | None:
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name or None

    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                targets = [node.module] + [f"{node.module}.{alias.name}" for alias in node.names]
            else:
                continue
            for target in targets:
                found = resolve(target)
                if found is not None and found != name and not name.startswith(found + "."):
                    graph[name].add(found)
    return graph


def test_no_import_cycle_between_project_modules() -> None:
    graph = _module_graph()
    assert len(graph) > 100
    cycles: list[list[str]] = []
    done: set[str] = set()

    def visit(node: str, path: list[str], on_path: set[str]) -> None:
        for nxt in sorted(graph[node]):
            if nxt in on_path:
                cycles.append([*path[path.index(nxt):], nxt])
            elif nxt not in done:
                path.append(nxt)
                on_path.add(nxt)
                visit(nxt, path, on_path)
                on_path.discard(nxt)
                path.pop()
        done.add(node)

    for start in sorted(graph):
        if start not in done:
            visit(start, [start], {start})
    assert cycles == []
