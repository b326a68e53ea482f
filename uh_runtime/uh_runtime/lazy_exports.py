"""The public names of a sub-package, each imported from its module the first time it is asked for (PEP 562).

A sub-package's ``__init__`` that imported all its modules would load them all whenever one of them is
imported: the rclpy backend's processes would load the Cyclone DDS backend for the QoS words of
:mod:`uh_runtime.dds.qos`, and ``python -m uh_runtime.bags.replay`` would find its module imported
already by its package (Python warns). With :func:`lazy_exports` a module loads only what it imports.
"""
import importlib
import sys

__all__ = ['lazy_exports']


def lazy_exports(package: str, homes: dict):
    """Return ``(__all__, __getattr__)`` for the ``__init__`` of ``package``.

    ``homes`` maps each module of the package (its name inside the package) to the public names it
    defines. The returned ``__getattr__`` imports a name's module when the name is first asked for
    (``from package import Name``, ``package.Name``, ``from package import *``) and keeps the name in
    the package, so later look-ups are plain attribute reads.
    """
    home_of = {name: module for module, names in homes.items() for name in names}

    def load(name):
        module = home_of.get(name)
        if module is None:
            raise AttributeError(f'module {package!r} has no attribute {name!r}')
        value = getattr(importlib.import_module(f'{package}.{module}'), name)
        setattr(sys.modules[package], name, value)
        return value

    return list(home_of), load
