"""Objectives from plugins in run configurations: their keys from the factory's signature.

A plugin objective's table in ``[[controller.objectives]]`` has ``type`` (the entry point's name), ``gain``
(its step gain, >= 0, required) and the factory's keyword parameters after the device: a parameter without
a default is required, any other key is refused by its path. Values are passed as TOML read them.
"""

from __future__ import annotations

import inspect
from collections.abc import Iterator, Mapping

from rhi import plugins
from rhi.errors import InvalidInput, RhiError
from rhi.plugins import PluginError
from rhi.runtime import schema as S

GROUP = "rhi.objectives"


def _as_read(path: str, v):
    return v


class ObjectiveSpecs(Mapping):
    """The specs of the objective types: `bundled` ({type: spec}) first, then each installed plugin's.

    Args:
        bundled: rhi's own objective types and their specs.
        gain: the spec entry of the step gain every objective has.
    """

    def __init__(self, bundled: Mapping[str, S.Spec], gain: S.Spec) -> None:
        self.bundled, self.gain = bundled, gain

    def __getitem__(self, kind: str) -> S.Spec:
        if kind in self.bundled:
            return self.bundled[kind]
        factory = plugins.load(GROUP, kind)
        if factory is None:
            raise KeyError(kind)
        try:
            sig = inspect.signature(factory)
        except (TypeError, ValueError) as exc:
            raise PluginError(f"objective plugin {kind!r}: no signature to read its keys from ({exc})") from None
        params = list(sig.parameters.values())[1:]  # the first is the device
        spec = dict(self.gain)
        for p in params:
            if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD) and p.name != "gain":
                spec[p.name] = (_as_read, S.REQUIRED if p.default is p.empty else p.default)
        return spec

    def __iter__(self) -> Iterator[str]:
        yield from self.bundled
        yield from (n for n in plugins.names(GROUP) if n not in self.bundled)

    def __len__(self) -> int:
        return len(list(iter(self)))


def build(path: str, kind: str, device, table: dict):
    """The objective of plugin type `kind` for `device`, from its parsed table (``type`` and ``gain`` left out).

    Raises:
        InvalidInput: the factory refused a value (its message after `path`).
        PluginError: the plugin gave no objective (an object without ``value`` and ``gradient``).
    """
    factory = plugins.load(GROUP, kind)
    params = {k: v for k, v in table.items() if k not in ("type", "gain")}
    try:
        obj = factory(device, **params)
    except RhiError as exc:
        raise type(exc)(f"{path}: {exc}") from None
    except (TypeError, ValueError) as exc:  # the plugin's own checks
        raise InvalidInput(f"{path}: objective plugin {kind!r} refused its parameters: {exc}") from None
    if not (callable(getattr(obj, "value", None)) and callable(getattr(obj, "gradient", None))):
        raise PluginError(f"{path}: objective plugin {kind!r} gave a {type(obj).__name__}, which has no "
                          "value(device, q) and gradient(device, q)")
    return obj


__all__ = ["ObjectiveSpecs", "build"]
