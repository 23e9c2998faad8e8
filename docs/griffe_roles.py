"""A griffe extension for the API reference: the docstrings' Sphinx roles as code.

The docstrings name other objects the Sphinx way (``:class:`~dqcontrol.sim.RunResult```,
``:func:`run_loop```); mkdocstrings reads Markdown, where such a role would show its
markup. Each role becomes inline code of its target: the last component with ``~``, else
the name as written (``RunResult``, ``run_loop``).
"""

from __future__ import annotations

import re
from typing import Any

import griffe

_ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|attr|data|exc|obj|const):`(~?)([^`]+)`")


def plain_roles(text: str) -> str:
    """``text`` with every Sphinx role replaced by inline code of its target."""

    def code(match: re.Match[str]) -> str:
        tilde, target = match.groups()
        return f"`{target.rsplit('.', 1)[-1] if tilde else target}`"

    return _ROLE.sub(code, text)


class SphinxRolesAsCode(griffe.Extension):
    """Rewrites the docstring of every object griffe loads (see the module docstring)."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        """Rewrite ``obj``'s docstring, if it has one."""
        if obj.docstring is not None:
            obj.docstring.value = plain_roles(obj.docstring.value)
