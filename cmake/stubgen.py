"""Run pybind11-stubgen on the freshly built module in MODULE_DIR.

Usage: python stubgen.py MODULE_DIR [pybind11-stubgen arguments...]

The module's folder goes in front of ``sys.path`` here, inside the
interpreter, instead of through the ``PYTHONPATH`` variable: pip's isolated
build provides its build requirements (pybind11-stubgen, numpy) through
``PYTHONPATH``, and replacing it hid them.
"""
import sys

from pybind11_stubgen import main

if __name__ == "__main__":
    sys.path.insert(0, sys.argv[1])
    main(sys.argv[2:])
