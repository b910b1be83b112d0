"""crlbswarm's public names, each with the module that defines it.

The package imports them lazily (``lazy_loader.attach_stub`` reads this file), and type
checkers read them from here: this stub is the one list of the package's exports.
"""

__version__: str
