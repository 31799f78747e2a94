"""Names a package exports but loads on first use (PEP 562), so that importing the package
(and so the command line's ``--help``) costs nothing until a name is used."""

from __future__ import annotations

import importlib

TYPE_CHECKING = False  # not typing's: importing the package stays cheap (turbinefit.cli.signals)
if TYPE_CHECKING:
    from collections.abc import Callable
    from typing import Any


def lazy_exports(package: str, where: dict[str, str]) -> Callable[[str], Any]:
    """A module ``__getattr__`` for ``package`` that loads each name of ``where`` ({name:
    module}) from its module when first asked for."""

    def __getattr__(name: str) -> Any:
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(module), name)

    return __getattr__
