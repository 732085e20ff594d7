"""A griffe extension for the API reference (mkdocs.yml, ``make docs``). It reads the
source and imports nothing; it changes what the site shows, never lookout.

Two things that reading the source does not give mkdocstrings as it is:

- The names that ``lookout`` and ``lookout.live`` import when they are first used
  (PEP 562). Each keeps them in a dict literal ``_PUBLIC`` (name -> the module that
  defines it, absolute or relative to the package) and imports them in the module's
  ``__getattr__``, so that ``import lookout`` imports neither JAX nor the models. Each
  name becomes an alias of its definition, listed in ``__all__``, so that ``::: lookout``
  documents ``lookout.simulate`` where a user calls it.
- The docstrings' Sphinx roles (:class:`Scenario`, :func:`~lookout.sim.simulate`,
  :mod:`.composition`). Each becomes a link to the object's entry where the site has
  one and inline code where it has none: a name is looked up from the docstring's own
  scope (its class, its module, their packages), and the link is an optional
  cross-reference, which falls back to code without a warning. A paragraph's closing ``::`` (a literal block follows)
  becomes ``:``.
"""

from __future__ import annotations

import ast
import html
import importlib.util
import re
from collections.abc import Iterator
from typing import Any

import griffe

ROLE = re.compile(r":(?:class|func|meth|mod|data|attr|obj|exc|const):`(?P<target>[^`<>]+)`")
LITERAL_BLOCK = re.compile(r"(?m)(\S)::$|^\s*::$")


def _objects(obj: griffe.Object, seen: set[str]) -> Iterator[griffe.Object]:
    if obj.is_alias or obj.path in seen:
        return
    seen.add(obj.path)
    yield obj
    for member in obj.members.values():
        yield from _objects(member, seen)


def _add_lazy_exports(module: griffe.Module) -> None:
    table = module.members.get("_PUBLIC")
    if table is None or table.is_alias or not table.is_attribute or table.value is None:
        return
    try:
        public = ast.literal_eval(str(table.value))
    except (ValueError, SyntaxError):
        return
    if not isinstance(public, dict):
        return
    for name, where in public.items():
        if name not in module.members:
            alias = griffe.Alias(name, f"{importlib.util.resolve_name(where, module.path)}.{name}", parent=module)
            alias.public = True
            module.set_member(name, alias)
    exports = [name for name in module.exports or () if isinstance(name, str)]
    module.exports = exports + [name for name in public if name not in exports]


def _lookup(package: griffe.Module, path: str) -> griffe.Object | griffe.Alias | None:
    if path == package.path:
        return package
    if not path.startswith(package.path + "."):
        return None
    try:
        return package[path[len(package.path) + 1 :]]
    except (KeyError, griffe.AliasResolutionError, griffe.CyclicAliasError):
        return None


def _canonical(found: griffe.Object | griffe.Alias) -> str:
    try:
        return found.canonical_path
    except (griffe.AliasResolutionError, griffe.CyclicAliasError):
        return found.path


def _resolve(package: griffe.Module, scope: griffe.Object, target: str) -> str | None:
    """The canonical path of ``target`` as written in a docstring of ``scope``, or None."""
    if target.startswith("."):  # relative to the module, then to its packages
        module = scope if scope.is_module else scope.module
        for base in (module, *_parents(module)):
            if (found := _lookup(package, base.path + target)) is not None:
                return _canonical(found)
        return None
    if (found := _lookup(package, target)) is not None:
        return _canonical(found)
    head, _, rest = target.partition(".")
    for where in (scope, *(parent for parent in _parents(scope))):
        try:
            resolved = where.resolve(head)
        except griffe.NameResolutionError:
            continue
        if (found := _lookup(package, f"{resolved}.{rest}" if rest else resolved)) is not None:
            return _canonical(found)
    return None


def _parents(obj: griffe.Object) -> Iterator[griffe.Object]:
    while obj.parent is not None:
        obj = obj.parent
        yield obj


def _link_roles(package: griffe.Module, obj: griffe.Object) -> None:
    docstring = obj.docstring
    if docstring is None:
        return

    def link(match: re.Match) -> str:
        target = match["target"].strip().lstrip("!")
        short = target.startswith("~")
        target = target.lstrip("~")
        title = target.rsplit(".", 1)[-1] if short else target.lstrip(".")
        path = _resolve(package, obj, target)
        if path is None:
            return f"`{title}`"
        return f'<autoref identifier="{html.escape(path)}" optional><code>{html.escape(title)}</code></autoref>'

    text = ROLE.sub(link, docstring.value)
    docstring.value = LITERAL_BLOCK.sub(lambda match: f"{match[1]}:" if match[1] else "", text)


class LookoutDocs(griffe.Extension):
    """Lazy exports as aliases, then the docstrings' roles as links."""

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        objects = list(_objects(pkg, set()))
        for obj in objects:
            if obj.is_module:
                _add_lazy_exports(obj)
        for obj in objects:
            _link_roles(pkg, obj)
