"""Plugins: device links, objectives and devices that other packages add to rhi, by Python entry points.

A lab's package declares them in its ``pyproject.toml``; once installed, rhi finds them by name::

    [project.entry-points."rhi.links"]        # URL scheme → link factory
    mylab = "mylab_rhi:open_link"             # rhi run DEVICE --link mylab://... --config ...
    [project.entry-points."rhi.objectives"]   # run configuration [[controller.objectives]] type → objective
    centering = "mylab_rhi:Centering"
    [project.entry-points."rhi.devices"]      # device name → device factory
    myarm = "mylab_rhi:my_arm"                # rhi measure myarm ..., [device] name = "myarm"

The objects:

- ``rhi.links``: ``factory(url, *, rate, config, realtime) -> DeviceLink`` (`rhi.runtime.link.DeviceLink`;
  `rate` [Hz], `config` the run's `rhi.runtime.config.RunConfig`, `realtime` False under ``--fast``);
- ``rhi.objectives``: ``factory(device, **params) -> Objective`` (`rhi.control.objectives.Objective`:
  ``value(device, q)``, ``gradient(device, q)``); its keyword parameters are the table's keys (besides
  ``type`` and ``gain``), TOML values as read (numbers, strings, lists);
- ``rhi.devices``: ``factory(**params) -> Device`` (the design parameters of ``--param`` or ``[device] params``).

A bundled name wins over a plugin's; a plugin that fails to load raises `PluginError` naming it.
"""

from __future__ import annotations

from importlib import metadata

from rhi.errors import InvalidInput, RhiError, UnknownDevice

GROUPS = ("rhi.links", "rhi.objectives", "rhi.devices")


class PluginError(RhiError):
    """A plugin's entry point could not be loaded, or its object did not give what rhi asked for."""


def _entry_points(group: str) -> dict[str, metadata.EntryPoint]:
    if group not in GROUPS:
        raise ValueError(f"group: one of {', '.join(GROUPS)}, got {group!r}")
    return {ep.name: ep for ep in metadata.entry_points(group=group)}


def names(group: str) -> list[str]:
    """The names the installed packages give in entry point `group` (one of `GROUPS`), sorted."""
    return sorted(_entry_points(group))


def provider(group: str, name: str) -> str:
    """The distribution (package) that provides `name` in `group`, or "" when none does."""
    ep = _entry_points(group).get(name)
    return "" if ep is None or ep.dist is None else f"{ep.dist.name} {ep.dist.version}"


def load(group: str, name: str):
    """The object entry point `name` of `group` points to, or None when no installed package gives that name.

    Raises:
        PluginError: the entry point exists but importing its object failed (the plugin and the cause named).
    """
    ep = _entry_points(group).get(name)
    if ep is None:
        return None
    try:
        return ep.load()
    except Exception as exc:  # the plugin's own import error, whatever it is
        raise PluginError(f"plugin {name!r} ({group}, {ep.value}): cannot be loaded: {type(exc).__name__}: {exc}") \
            from exc


def device(name: str, params: dict, cls: type):
    """The device of plugin `name` (``rhi.devices``) built with `params`, for `rhi.device` (an instance of `cls`).

    Raises:
        UnknownDevice: no installed plugin gives that name.
        InvalidInput: the factory refused a parameter.
        PluginError: the plugin failed to load or gave no `cls`.
    """
    factory = load("rhi.devices", name)
    if factory is None:
        raise UnknownDevice(f"name: no device plugin {name!r}; plugins: {', '.join(names('rhi.devices')) or 'none'}")
    try:
        dev = factory(**params)
    except TypeError as exc:  # the factory's own signature refused a parameter
        raise InvalidInput(f"params: device plugin {name!r}: {exc}") from None
    if not isinstance(dev, cls):
        raise PluginError(f"device plugin {name!r} gave a {type(dev).__name__}, not a {cls.__name__}")
    return dev


def link(url: str, *, rate: float, config, realtime: bool):
    """The device link of a plugin's URL scheme (``rhi.links``): ``factory(url, rate=, config=, realtime=)``.

    Raises:
        InvalidInput: no installed plugin serves the URL's scheme (the plugins' schemes listed).
        PluginError: the plugin failed to load or gave no link (``open``, ``read``, ``write``, ``close``).
    """
    scheme = url.partition("://")[0] if "://" in url else ""
    factory = load("rhi.links", scheme) if scheme else None
    if factory is None:
        more = names("rhi.links")
        raise InvalidInput(f"--link: expected sim or udp://HOST:PORT (e.g. udp://127.0.0.1:5005)"
                           f"{', or a plugin scheme (' + ', '.join(s + '://' for s in more) + ')' if more else ''}, "
                           f"got {url!r}")
    try:
        made = factory(url, rate=rate, config=config, realtime=realtime)
    except RhiError as exc:
        raise type(exc)(f"--link: {exc}") from None
    if not all(callable(getattr(made, m, None)) for m in ("open", "read", "write", "close")):
        raise PluginError(f"link plugin {scheme!r} gave a {type(made).__name__}, not a device link "
                          "(open, read, write, close)")
    return made


__all__ = ["GROUPS", "PluginError", "device", "link", "load", "names", "provider"]
