"""Write ``docs/api.md``: the public API of dqcontrol, from its docstrings and signatures.

Run ``python docs/generate_api.py`` after changing a public signature or docstring;
``tests/test_docs.py`` fails while the page is out of date.
"""

from __future__ import annotations

import importlib
import inspect
import re
import sys
from pathlib import Path

#: The public packages, in the order of the pipeline.
MODULES = (
    "dqcontrol",
    "dqcontrol.model",
    "dqcontrol.dq",
    "dqcontrol.trajectories",
    "dqcontrol.controllers",
    "dqcontrol.registry",
    "dqcontrol.sim",
    "dqcontrol.runs",
    "dqcontrol.viz",
    "dqcontrol.experiments",
    "dqcontrol.faults",
    "dqcontrol.errors",
)

OUT = Path(__file__).resolve().parent / "api.md"


def _signature(obj) -> str:
    try:
        sig = str(inspect.signature(obj))
    except (TypeError, ValueError):
        return "(...)"
    return re.sub(r" at 0x[0-9a-f]+", "", sig)


def _doc(obj) -> str:
    doc = inspect.getdoc(obj) or ""
    return doc.strip()


def _first_paragraph(obj) -> str:
    return _doc(obj).split("\n\n")[0].replace("\n", " ")


def _own_methods(cls) -> list[tuple[str, object]]:
    out = []
    for name, member in vars(cls).items():
        if name.startswith("_"):
            continue
        if isinstance(member, property):
            out.append((name, member))
        elif inspect.isfunction(member) or isinstance(member, classmethod | staticmethod):
            out.append((name, member))
    return out


def _entry(module_name: str, name: str, obj) -> list[str]:
    lines: list[str] = []
    if inspect.isclass(obj):
        lines.append(f"### class `{name}{_signature(obj)}`")
        lines.append("")
        lines.append(_doc(obj))
        methods = _own_methods(obj)
        if methods:
            lines.append("")
            for meth_name, member in methods:
                if isinstance(member, property):
                    lines.append(f"- `{meth_name}` (property) — {_first_paragraph(member)}")
                else:
                    func = member.__func__ if hasattr(member, "__func__") else member
                    lines.append(f"- `{meth_name}{_signature(func)}` — {_first_paragraph(func)}")
    elif callable(obj):
        lines.append(f"### `{name}{_signature(obj)}`")
        lines.append("")
        lines.append(_doc(obj))
    else:
        lines.append(f"### `{name}`")
        lines.append("")
        lines.append(f"Constant: `{obj!r}`" if len(repr(obj)) < 200 else type(obj).__name__)
    lines.append("")
    return lines


def render() -> str:
    """The text of ``docs/api.md``."""
    lines = [
        "# API reference",
        "",
        "Generated from the docstrings by `python docs/generate_api.py` (do not edit by hand).",
        "Units are in the parameter names (`_s`, `_m`, `_rad`) or in brackets in the text.",
        "",
    ]
    for module_name in MODULES:
        module = importlib.import_module(module_name)
        names = getattr(module, "__all__", [])
        lines.append(f"## `{module_name}`")
        lines.append("")
        lines.append(_first_paragraph(module))
        lines.append("")
        for name in names:
            obj = getattr(module, name)
            if inspect.ismodule(obj):
                continue
            lines.extend(_entry(module_name, name, obj))
    return "\n".join(lines).rstrip() + "\n"


def main() -> int:
    OUT.write_text(render(), encoding="utf-8")
    print(f"wrote {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
