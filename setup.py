"""The optional C extension spq._entry (spq.query falls back to Python where it cannot be built).

Everything else is in pyproject.toml. An editable install (pip install -e .) builds it in place,
next to spq/query.py, where the tests import it from.
"""

import numpy
from setuptools import Extension, setup

setup(ext_modules=[Extension("spq._entry", ["spq/_entry.c"], include_dirs=[numpy.get_include()], optional=True)])
