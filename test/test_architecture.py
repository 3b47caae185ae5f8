"""The floors of docs/architecture.md hold for the code: every import of a vm_ros module (also
inside a function) runs from a room to one on a lower floor, or stays inside its room."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROW = re.compile(r"^\| (\d+) \| `([^`]+)` \|")


def floors() -> dict[str, int]:
    """{room path: floor} from the table of docs/architecture.md."""
    text = (ROOT / "docs/architecture.md").read_text()
    return {m.group(2): int(m.group(1)) for m in map(ROW.match, text.splitlines()) if m}


def room_of(path: str, rooms) -> str | None:
    """The room holding ``path`` (a file, or a module path without suffix): the longest room
    that is the path itself or a folder above it."""
    held = [r for r in rooms if path == r.removesuffix(".py") or path == r
            or (r.endswith("/") and path.startswith(r))]
    return max(held, key=len, default=None)


def imported_paths(tree: ast.AST):
    """The module paths (vm_ros/x/y) each vm_ros import of ``tree`` names, with its line."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("vm_ros"):
                    yield alias.name.replace(".", "/"), node.lineno
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                and node.module.split(".")[0] == "vm_ros":
            base = node.module.replace(".", "/")
            for alias in node.names:  # ``from vm_ros.x import y``: module y if there is one
                yield f"{base}/{alias.name}", node.lineno


def test_the_table_names_every_room_of_the_package_once():
    rooms = floors()
    assert len(rooms) >= 15
    for room in rooms:
        assert (ROOT / room).exists(), room
    files = sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "vm_ros").rglob("*.py"))
    files.remove("vm_ros/__init__.py")  # the package's face: it defines and imports nothing
    assert [f for f in files if room_of(f, rooms) is None] == []


def test_every_import_runs_down_a_floor():
    rooms = floors()
    up = []
    for folder in ("vm_ros", "bench"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            source = path.relative_to(ROOT).as_posix()
            here = room_of(source, rooms)
            for target, line in imported_paths(ast.parse(path.read_text())):
                there = room_of(target, rooms) or room_of(target.rsplit("/", 1)[0], rooms)
                if there is None or there == here:
                    continue
                if rooms[there] >= rooms[here]:
                    up.append(f"{source}:{line} imports {target} (floor {rooms[here]} -> "
                              f"{rooms[there]})")
    assert up == []


def test_an_import_up_is_caught():
    """The check itself: a model module importing the node would be reported."""
    rooms = floors()
    tree = ast.parse("def f():\n    from vm_ros.node.inputs import NodeInputs\n")
    (target, _), = imported_paths(tree)
    assert rooms[room_of(target, rooms)] > rooms[room_of("vm_ros/model/bank.py", rooms)]
