"""Sphinx configuration of the API reference, built from the docstrings.

Build it from the repository root (the README's command):
``python -m sphinx -W -b html docs/api out/api``.
"""

project = "snn-fg"
author = "snn-fg developers"
copyright = "2025, snn-fg developers"

extensions = [
    "sphinx.ext.autodoc",  # members and signatures read from the code
    "sphinx.ext.autosummary",  # one page per module, made at build time (generated/, not in git)
    "sphinx.ext.napoleon",  # the numpydoc sections (Parameters, Returns, Examples)
]
templates_path = ["_templates"]
exclude_patterns = ["_build"]

autosummary_generate = True
#: modules left out of the reference (the module template skips them): the ``snn-fg`` command's entry point
#: (importing it runs the command), the PyNN, Lava and NIR exports' ``run.py`` programs (they import their
#: sibling modules by their names in an export folder)
autosummary_context = {
    "skipped": ["snn_fg.cli.__main__", "snn_fg.pynn.run", "snn_fg.lava.run", "snn_fg.export.snntorch_loop.run"]
}
# Lava (an export folder's own Python 3.10 environment, not an extra of snn-fg): imitated, so that the Lava
# processes' module is documented
autodoc_mock_imports = ["lava"]
# each object documented once, in the module that defines it (a package's ``__all__`` re-exports are not repeated)
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}
autodoc_member_order = "bysource"
# signatures read as written (the modules postpone their annotations)
autodoc_typehints = "signature"
napoleon_google_docstring = False
napoleon_numpy_docstring = True

# the docstrings write an absolute value as |x|, which reStructuredText would read as a substitution
rst_prolog = "\n".join(
    f".. |{x}| replace:: \\|{x}\\|" for x in ("value", "weight", "kernel value", "u", "v", "a_in", "drive", "current")
)

html_theme = "alabaster"
html_title = "snn-fg API reference"

#: what autodoc calls a constant, an attribute and a property
_PROSE = ("data", "attribute", "property")


def _defined_at(target: str, module: str | None) -> str | None:
    """Where the object a cross-reference names is defined (``module.qualname``), when the
    reference names it by a path that re-exports it (``snn_fg.network.Network``) or by a
    name its module imports (``iter_recording`` in :mod:`snn_fg.events.window`); None if
    it names no class or function of snn_fg's (an attribute: its class's, then its own name)."""
    import importlib

    def lookup(path: str):
        parts = path.split(".")
        if not all(parts):  # (a relative name, ``.core``: Sphinx resolves those itself)
            return None
        for cut in range(len(parts) - 1, 0, -1):
            try:
                obj = importlib.import_module(".".join(parts[:cut]))
            except Exception:  # (a module that cannot be imported here: the reference stays unresolved)
                continue
            try:
                for name in parts[cut:]:
                    obj = getattr(obj, name)
            except AttributeError:
                return None
            return obj
        return None

    def assigned_in(name: str, value) -> str | None:
        """The snn_fg module whose own source assigns ``name`` (a constant has no ``__module__``)."""
        import inspect
        import re
        import sys

        for modname, mod in sorted(sys.modules.items()):
            if modname.startswith("snn_fg") and getattr(mod, name, None) is value:
                try:
                    source = inspect.getsource(mod)
                except (OSError, TypeError):
                    continue
                # (NAME = ..., NAME: type = ..., or one of the names of A, NAME, B = ...)
                if re.search(rf"^(?:\w+\s*,\s*)*{re.escape(name)}\b[^=\n]*=", source, re.M):
                    return f"{modname}.{name}"
        return None

    candidates = [target] + ([f"{module}.{target}"] if module else [])
    for path in candidates:
        head, _, attr = path.rpartition(".")
        for obj, rest in ((lookup(path), ""), (lookup(head), attr)):
            where = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
            if where[0] and where[1] and where[0].startswith("snn_fg"):
                return ".".join(filter(None, (*where, rest)))
        parent = lookup(head) if head else None
        if type(parent).__name__ == "module" and hasattr(parent, attr):
            return assigned_in(attr, getattr(parent, attr))
    return None


def setup(app):
    """Constants', attributes' and properties' docstrings (the ``#:`` comments)
    are prose, read as written: napoleon would take whatever precedes a first
    colon as the object's type. A cross-reference to an object by a path that
    re-exports it is sent to the page where it is defined (each object is
    documented once, there)."""
    written = {}

    def reexported(app, env, node, contnode):
        if node.get("refdomain") != "py":
            return None
        real = _defined_at(node["reftarget"], node.get("py:module"))
        if real is None or real == node["reftarget"]:
            return None
        py = env.get_domain("py")
        return py.resolve_xref(env, node["refdoc"], app.builder, node["reftype"], real, node, contnode)

    app.connect("missing-reference", reexported)

    def keep(app, what, name, obj, options, lines):
        if what in _PROSE:
            written[name] = list(lines)

    def restore(app, what, name, obj, options, lines):
        if what in _PROSE and name in written:
            lines[:] = written.pop(name)

    # napoleon rewrites docstrings at the default priority (500): keep them before, restore them after
    app.connect("autodoc-process-docstring", keep, priority=400)
    app.connect("autodoc-process-docstring", restore, priority=600)
