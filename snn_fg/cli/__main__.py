"""``python -m snn_fg.cli``: the ``snn-fg`` command."""

from .main import console

if __name__ == "__main__":  # (not when a tool imports the package's modules, as the API reference's build does)
    console()
