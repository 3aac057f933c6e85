"""mkdocs hook: the docstrings' Sphinx roles (``:class:`~a.b.C```, ``:func:`f```) as code.

The package's docstrings are Google style with Sphinx cross-reference roles, which
mkdocstrings renders literally (``:class:<code>~a.b.C</code>``); this shows the name as code,
without the role and (for ``~``) with only its last component, as Sphinx would.
"""

from __future__ import annotations

import re
from typing import Any

_ROLE = re.compile(r":(?:class|func|meth|mod|data|attr|exc|obj|const):<code>(~?)([^<]+)</code>")


def _short(match: re.Match[str]) -> str:
    name = match.group(2)
    return f"<code>{name.rsplit('.', 1)[-1] if match.group(1) else name}</code>"


def on_page_content(html: str, **_: Any) -> str:
    """Rewrite every role in the rendered page."""
    return _ROLE.sub(_short, html)
