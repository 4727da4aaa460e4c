"""Outside methods beside the built-ins: trackers, servo laws (controllers) and policies, one mechanism for the three.

A method is named in one of four ways, the same for every kind and everywhere a built-in is accepted:
- a built-in name (`hybrid`, `ibvs`, ...);
- a name registered in Python: `hvs_sim.register_tracker("mine", make)` (and `register_controller`, `register_policy`);
- a name an installed package declares as an entry point in the group `hvs_sim.trackers`, `hvs_sim.controllers` or
  `hvs_sim.policies` (`[project.entry-points."hvs_sim.trackers"] mine = "mypkg.track:make"`);
- a reference `package.module:callable`, or a file `path/to/file.py:callable`.

The callable is a factory: called with the method's settings (keywords), it returns
- a tracker: `init(frame, roi)` and `update(frame)` returning a Track-like object or mapping with `corners` (4×2
  pixels; `center`, `mode`, `occlusion`, `score`, `confidence` optional), and a `warp` attribute ("similarity" or
  "homography": the DOFs its corners observe); `seed(A)` optional (teach-by-showing);
- a controller: `compute(ControlInput) -> twist` (control/protocol.py), and optionally `dofs` (what it commands) and
  `uses_features` (False for a law that reads only the images);
- a policy: `act(PolicyInput) -> twist`, optionally `reset(PolicyInput)` at the first step and `dofs`.

An outside method is checked as a built-in is: its output is validated every step, and a malformed or non-finite
answer (or an exception) is a recorded fault: the arm holds for that step and the run goes on.

Benchmark and sweep workers are other processes: they get a portable spelling of each method (`portable`), the
module:callable or file a name resolves to, and import it again there; a name registered only in a script's
`__main__` cannot travel and is refused with the reason.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib
import importlib.util
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from hvs_sim.errors import ConfigError, HvsError
from hvs_sim.external import ExternalController, ExternalPolicy, ExternalTracker

KINDS = ("tracker", "controller", "policy")
GROUPS = {"tracker": "hvs_sim.trackers", "controller": "hvs_sim.controllers", "policy": "hvs_sim.policies"}  # entry points
GROUND_TRUTH = "ground_truth"  # the oracle: the loop's features from the simulator
NO_TRACKER = "none"  # no tracker: for laws that read only the images (dvs) and for policies
PLUGIN_TIMEOUT_S = 120.0  # an outside module's import or factory that has not returned by then is stopped as hung
# what a plugin object must have, by kind
INTERFACE = {"tracker": ("init", "update"), "controller": ("compute",), "policy": ("act",)}


class PluginTimeout(ConfigError):
    """An outside module's import or factory did not return within PLUGIN_TIMEOUT_S."""


@contextlib.contextmanager
def _time_limit(what: str):
    """Stop user code that hangs (SIGALRM, in the main thread, where Python code can be interrupted) with a
    PluginTimeout naming it; elsewhere (a worker thread), or under a caller's own alarm, it is left to that."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread() or not PLUGIN_TIMEOUT_S or \
            signal.getitimer(signal.ITIMER_REAL)[0] > 0:  # another timer (the caller's own) is already watching
        yield
        return
    limit = PLUGIN_TIMEOUT_S

    def expire(signum, frame):
        raise PluginTimeout(f"{what} did not return within {limit:g} s (hvs_sim.plugins.PLUGIN_TIMEOUT_S) and was "
                            "stopped; a factory must build its method and return it")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, limit)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _outside_failure(exc: BaseException) -> str:
    """How outside code failed, for a message: an exception, or a sys.exit (which is not a result)."""
    if isinstance(exc, SystemExit):
        return f"as it called sys.exit({exc.code!r}), which a plugin may not do (return or raise instead)"
    return f"{type(exc).__name__}: {exc}"


@dataclass(frozen=True)
class Plugin:
    kind: str
    name: str  # as written (a name, or the reference itself)
    factory: Callable
    ref: str | None  # portable spelling: module:callable or file.py:callable (None: not importable elsewhere)
    source: str  # "python", "entry point (DIST)", "reference"
    description: str = ""


_REGISTERED: dict[str, dict[str, Plugin]] = {kind: {} for kind in KINDS}


def builtin_names(kind: str) -> tuple[str, ...]:
    """The built-in names of a kind (plugins may not take them)."""
    if kind == "tracker":
        from hvs_sim.tracking.registry import TRACKER_NAMES

        return (GROUND_TRUTH, NO_TRACKER, *TRACKER_NAMES)
    if kind == "controller":
        from hvs_sim.control.laws.ibvs import CONTROLLERS

        return CONTROLLERS
    return ()


def _check_kind(kind: str) -> None:
    if kind not in KINDS:
        raise ConfigError(f"unknown plugin kind {kind!r}; accepted: {', '.join(KINDS)}")


def is_reference(text: str) -> bool:
    """Whether a method's spelling is a `module:callable` or `file.py:callable` reference rather than a name."""
    return isinstance(text, str) and ":" in text


def _portable_ref(factory: Callable) -> str | None:
    """module:qualname of a factory when another process can import it (not a script's __main__, not a closure)."""
    module, qualname = getattr(factory, "__module__", None), getattr(factory, "__qualname__", "")
    if not module or module == "__main__" or "<" in qualname:
        return None
    if not qualname:  # functools.partial and other callables without a name
        return None
    obj = sys.modules.get(module)
    for part in qualname.split("."):
        obj = getattr(obj, part, None)
    if obj is not factory:  # a bound method, a wrapped function: the name does not give this factory back
        return None
    if module.startswith("hvs_sim._plugin_file_"):  # loaded from a file: the file again
        base = getattr(sys.modules.get(module), "__hvs_plugin_ref__", None)
        return base + qualname if base else None
    return f"{module}:{qualname}"


def _register(kind: str, name: str, factory: Callable, description: str, replace: bool) -> None:
    _check_kind(kind)
    if not isinstance(name, str) or not name or is_reference(name) or any(c in name for c in "/{}= \t"):
        raise ConfigError(f"{kind} plugin name {name!r} invalid; accepted: a non-empty name without ':', '/', '=', "
                          "braces or spaces")
    if name in builtin_names(kind):
        raise ConfigError(f"{kind} name {name!r} is a built-in; pick another name (built-ins: "
                          f"{', '.join(builtin_names(kind))})")
    if not callable(factory):
        raise ConfigError(f"register_{kind}({name!r}, ...): the factory must be callable, got {type(factory).__name__}")
    if name in _REGISTERED[kind] and not replace and _REGISTERED[kind][name].factory is not factory:
        raise ConfigError(f"{kind} {name!r} is already registered; pass replace=True to replace it")
    _REGISTERED[kind][name] = Plugin(kind, name, factory, _portable_ref(factory), "python", description)


def register_tracker(name: str, factory: Callable, *, description: str = "", replace: bool = False) -> None:
    """Make `factory(**settings) -> tracker` available as tracker `name` (module docstring: the contract)."""
    _register("tracker", name, factory, description, replace)


def register_controller(name: str, factory: Callable, *, description: str = "", replace: bool = False) -> None:
    """Make `factory(**settings) -> law` (compute(ControlInput) -> twist) available as controller `name`."""
    _register("controller", name, factory, description, replace)


def register_policy(name: str, factory: Callable, *, description: str = "", replace: bool = False) -> None:
    """Make `factory(**settings) -> policy` (act(PolicyInput) -> twist) available as policy `name`."""
    _register("policy", name, factory, description, replace)


def unregister(kind: str, name: str) -> None:
    """Remove a name registered in Python (tests; a notebook re-defining a method)."""
    _check_kind(kind)
    _REGISTERED[kind].pop(name, None)


def _entry_points(kind: str) -> dict:
    from importlib.metadata import entry_points

    return {ep.name: ep for ep in entry_points(group=GROUPS[kind])}


def available(kind: str) -> dict[str, str]:
    """Every outside name of a kind (registered, then entry points) → where it comes from."""
    _check_kind(kind)
    out = {name: "python" for name in _REGISTERED[kind]}
    for name, ep in _entry_points(kind).items():
        dist = getattr(getattr(ep, "dist", None), "name", None) or "an installed package"
        out.setdefault(name, f"entry point {ep.value} ({dist})")
    return out


def accepted_text(kind: str) -> str:
    names = [*builtin_names(kind), *available(kind)]
    return (", ".join(names) + ("; or " if names else "") + "a reference package.module:callable or "
            "path/to/file.py:callable")


def _load_file(path: str) -> object:
    try:
        p = Path(path).expanduser().resolve()
    except (OSError, RuntimeError) as exc:  # a link loop
        raise ConfigError(f"plugin file {path!r} cannot be resolved ({exc})") from None
    if not p.is_file():
        raise ConfigError(f"plugin file {path!r} not found or not a regular file (resolved to {p})")
    if p.suffix != ".py":
        raise ConfigError(f"plugin file {path!r} is not a Python file; accepted: path/to/file.py:callable")
    name = "hvs_sim._plugin_file_" + hashlib.sha1(str(p).encode()).hexdigest()[:12]
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, p)
    if spec is None or spec.loader is None:
        raise ConfigError(f"plugin file {path!r} cannot be imported as Python; accepted: path/to/file.py:callable")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        with _time_limit(f"importing plugin file {path!r}"):
            spec.loader.exec_module(module)
    except PluginTimeout:
        del sys.modules[name]
        raise
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - any failure of outside code becomes a ConfigError
        del sys.modules[name]
        raise ConfigError(f"plugin file {path!r} failed to import{' ' if isinstance(exc, SystemExit) else ': '}"
                          f"{_outside_failure(exc)}") from None
    module.__hvs_plugin_ref__ = f"{p}:"  # + a callable's name: the file's portable reference (_portable_ref)
    return module


def _load_reference(kind: str, ref: str) -> Plugin:
    target, _, attr = ref.rpartition(":")
    if not target or not attr:
        raise ConfigError(f"{kind} reference {ref!r} invalid; accepted: package.module:callable or "
                          "path/to/file.py:callable")
    if target.endswith(".py") or "/" in target or "\\" in target:
        module = _load_file(target)
        portable = f"{Path(target).expanduser().resolve()}:{attr}"
    else:
        try:
            with _time_limit(f"importing module {target!r}"):
                module = importlib.import_module(target)
        except PluginTimeout:
            raise
        except (Exception, SystemExit) as exc:  # noqa: BLE001 - ImportError, or the module's own import-time error
            raise ConfigError(f"cannot import module {target!r} for {kind} {ref!r} ({_outside_failure(exc)}); the "
                              "module must be importable by this Python (installed, on PYTHONPATH, or given as a file "
                              "path/to/file.py:callable); on Ray it must be importable on every worker") from None
        portable = ref
    obj = module
    for part in attr.split("."):
        if not hasattr(obj, part):
            names = sorted(n for n in dir(module) if not n.startswith("_") and callable(getattr(module, n)))
            raise ConfigError(f"{target!r} has no attribute {attr!r} for {kind} {ref!r}; its callables: "
                              f"{', '.join(names) or 'none'}")
        obj = getattr(obj, part)
    if not callable(obj):
        raise ConfigError(f"{kind} {ref!r} names {type(obj).__name__}, not a callable factory")
    return Plugin(kind, ref, obj, portable, "reference")


def resolve(kind: str, text: str) -> Plugin | None:
    """The outside method a spelling names; None for a built-in. ConfigError naming what is accepted otherwise."""
    _check_kind(kind)
    if not isinstance(text, str) or not text:
        raise ConfigError(f"{kind} must be a name or reference; accepted: {accepted_text(kind)}")
    if text in builtin_names(kind):
        return None
    if is_reference(text):
        return _load_reference(kind, text)
    if text in _REGISTERED[kind]:
        return _REGISTERED[kind][text]
    eps = _entry_points(kind)
    if text in eps:
        ep = eps[text]
        try:
            with _time_limit(f"{kind} entry point {text!r} ({ep.value})"):
                factory = ep.load()
        except PluginTimeout:
            raise
        except (Exception, SystemExit) as exc:  # noqa: BLE001 - any failure of outside code becomes a ConfigError
            raise ConfigError(f"{kind} entry point {text!r} ({ep.value}) failed to load: {_outside_failure(exc)}") \
                from None
        if not callable(factory):
            raise ConfigError(f"{kind} entry point {text!r} ({ep.value}) is not callable")
        return Plugin(kind, text, factory, ep.value, f"entry point ({ep.value})")
    raise ConfigError(f"unknown {kind} {text!r}; accepted: {accepted_text(kind)}")


def check(kind: str, text: str) -> None:
    """ConfigError unless `text` names a built-in or an outside method of this kind (imports it, builds nothing)."""
    resolve(kind, text)


def portable(kind: str, text: str) -> str:
    """A spelling of the method another process resolves to the same factory: built-ins, entry points and references
    as they are; a name registered in Python as its module:callable (ConfigError when it has none)."""
    plugin = resolve(kind, text)
    if plugin is None or plugin.source != "python":
        return plugin.ref if plugin is not None and plugin.source == "reference" else text
    if plugin.ref is None:
        raise ConfigError(f"{kind} {text!r} was registered in Python from a script or a closure, which worker processes "
                          "cannot import: run with one worker, or register a module-level function of an importable "
                          "module (or give it as module:callable, or as an entry point)")
    return plugin.ref


def build(kind: str, text: str, **settings):
    """A fresh outside method from its factory, checked for its interface (ConfigError saying what is missing)."""
    plugin = resolve(kind, text)
    if plugin is None:
        raise ConfigError(f"{kind} {text!r} is a built-in, not a plugin")
    try:
        with _time_limit(f"{kind} {text!r}'s factory"):
            obj = plugin.factory(**settings)
    except HvsError:
        raise
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - any failure of outside code becomes a ConfigError
        how = _outside_failure(exc) if isinstance(exc, SystemExit) else f"with {_outside_failure(exc)}"
        raise ConfigError(f"{kind} {text!r}: its factory failed {how}") from None
    missing = [m for m in INTERFACE[kind] if not callable(getattr(obj, m, None))]
    if missing:
        raise ConfigError(f"{kind} {text!r}: its factory returned {type(obj).__name__}, which lacks "
                          f"{', '.join(missing)}(); a {kind} needs {', '.join(m + '()' for m in INTERFACE[kind])}")
    if kind == "tracker":
        return ExternalTracker(obj, text)
    if kind == "controller":
        return ExternalController(obj, text)
    return ExternalPolicy(obj, text)


# ------------------------------------------------------------------------ trackers by any spelling


def probe(kind: str, text: str | None) -> None:
    """Build an outside method once and drop it: a factory that fails, hangs or returns an object without the
    interface is refused before a benchmark's first episode, not after the methods before it have run."""
    if text and resolve(kind, text) is not None:
        build(kind, text)


def make_any_tracker(text: str, **settings):
    """A fresh tracker from a registry name (tracking/registry.py) or an outside tracker (this module's spellings)."""
    from hvs_sim.tracking import TRACKER_NAMES, make_tracker

    if text in TRACKER_NAMES:
        return make_tracker(text, **settings)
    return build("tracker", text, **settings)


def check_any_tracker(text: str) -> str:
    """`text` when it names a registry tracker or an outside one (not ground_truth or none); ConfigError otherwise."""
    from hvs_sim.tracking import TRACKER_NAMES

    if text in (GROUND_TRUTH, NO_TRACKER) or (text not in TRACKER_NAMES and resolve("tracker", text) is None):
        raise ConfigError(f"{text!r} is not a tracker of footage; accepted: {', '.join(TRACKER_NAMES)}, or an outside "
                          "tracker (a registered or entry-point name, module:callable, path/to/file.py:callable)")
    return text
