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


def setup(app):
    """Constants', attributes' and properties' docstrings (the ``#:`` comments)
    are prose, read as written: napoleon would take whatever precedes a first
    colon as the object's type."""
    written = {}

    def keep(app, what, name, obj, options, lines):
        if what in _PROSE:
            written[name] = list(lines)

    def restore(app, what, name, obj, options, lines):
        if what in _PROSE and name in written:
            lines[:] = written.pop(name)

    # napoleon rewrites docstrings at the default priority (500): keep them before, restore them after
    app.connect("autodoc-process-docstring", keep, priority=400)
    app.connect("autodoc-process-docstring", restore, priority=600)
