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
import time
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hvs_sim.errors import ConfigError, HvsError

KINDS = ("tracker", "controller", "policy")
GROUPS = {"tracker": "hvs_sim.trackers", "controller": "hvs_sim.controllers", "policy": "hvs_sim.policies"}  # entry points
GROUND_TRUTH = "ground_truth"  # the oracle: the loop's features from the simulator
NO_TRACKER = "none"  # no tracker: for laws that read only the images (dvs) and for policies
PLUGIN_TIMEOUT_S = 120.0  # an outside module's import or factory that has not returned by then is stopped as hung
# what a plugin object must have, by kind
INTERFACE = {"tracker": ("init", "update"), "controller": ("compute",), "policy": ("act",)}


class PluginFault(HvsError, ValueError):
    """An outside method's answer was malformed (the loop records it as the step's fault)."""


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
        from hvs_sim.control.ibvs import CONTROLLERS

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


# ------------------------------------------------------------------------ adapters: outside methods, checked


def _field(out, key, default=None):
    if isinstance(out, Mapping):
        return out.get(key, default)
    return getattr(out, key, default)


CONTRACT_TOL_PX = 0.2  # a first answer this close to the ROI's own corners keeps the contract
CONTRACT_ROUTE = "docs/plugins.md, the corner convention"


class ContractWarning(UserWarning):
    """An outside tracker's first answer looks like another corner convention than hvs_sim's."""


def contract_note(corners: np.ndarray, expected: np.ndarray) -> str | None:
    """Why an outside tracker's answer on its own template frame (where it should give the ROI back) looks like
    another convention: half a pixel off (corners on pixel centres, or (x, y)…(x + w, y + h)), or another order.
    None when it keeps the contract or differs in a way that is not a convention (an honest tracking error)."""
    err = float(np.abs(corners - expected).max())
    if err <= CONTRACT_TOL_PX:
        return None
    for shift in ((0.5, 0.5), (-0.5, -0.5)):
        if np.abs(corners - (expected + shift)).max() <= CONTRACT_TOL_PX:
            return (f"its corners are half a pixel off the ROI it was given ({shift[0]:+.1f}, {shift[1]:+.1f} px): "
                    "hvs_sim's corners are the outer pixel edges, from (x − 0.5, y − 0.5) to (x + w − 0.5, "
                    f"y + h − 0.5) ({CONTRACT_ROUTE})")
    orders = {"counter-clockwise": [0, 3, 2, 1], **{f"starting at corner {k}": list(np.roll(range(4), -k))
                                                   for k in (1, 2, 3)}}
    for name, order in orders.items():
        if np.abs(corners - expected[order]).max() <= CONTRACT_TOL_PX + 0.5:
            return (f"its corners come in another order ({name}): hvs_sim's are top-left, top-right, bottom-right, "
                    f"bottom-left ({CONTRACT_ROUTE})")
    return None


class ExternalTracker:
    """An outside tracker behind hvs_sim's tracker contract: its answers turned into Tracks and checked. Its first
    answer on the frame it was given the ROI on is compared with that ROI (`contract_note`): a tracker written to
    another corner convention is told at step 0, not after a benchmark that failed without a reason."""

    def __init__(self, inner, name: str):
        from hvs_sim.tracking.warp import WARPS

        self.inner, self.name = inner, name
        self.warp = getattr(inner, "warp", "similarity")
        if self.warp not in WARPS:
            raise ConfigError(f"tracker {name!r} declares warp {self.warp!r}; accepted: {', '.join(WARPS)} (which DOFs "
                              "its corners observe)")
        self.can_seed = callable(getattr(inner, "seed", None))
        # the loop's help near the goal (a template grown into the target's plane, given through init and seed) is
        # offered to every tracker with a goal template; one that cannot use it declines by `near_goal = False`
        self.near_goal = bool(getattr(inner, "near_goal", True))
        self.corners0 = None
        self.contract_note: str | None = None
        self._first, self._frame0 = True, None  # the next answer is the first on the ROI's frame (none seeded since)

    def init(self, frame, roi):
        from hvs_sim.tracking.frames import check_frame, check_roi, roi_corners

        frame = check_frame(frame)
        roi = check_roi(roi, frame.shape[:2])
        self.corners0 = roi_corners(roi)
        t0 = time.perf_counter()
        out = self.inner.init(frame, roi)
        self._first, self._frame0 = True, frame
        return None if out is None else self._checked(self._track(out, 1e3 * (time.perf_counter() - t0)))

    def seed(self, A) -> None:
        if not self.can_seed:
            raise ConfigError(f"tracker {self.name!r} has no seed(A): it cannot take a template from the goal image; "
                              "use template_from='start'")
        self._first = False  # later answers are on other frames, at seeded corners
        self.inner.seed(np.asarray(A, float))

    def update(self, frame):
        t0 = time.perf_counter()
        out = self.inner.update(frame)
        track = self._track(out, 1e3 * (time.perf_counter() - t0))
        if self._first and not (frame is self._frame0 or np.array_equal(frame, self._frame0)):
            self._first = False  # the first update is on another frame: the ROI is no longer its answer
        return self._checked(track)

    def _checked(self, track):
        """The first answer after init, compared with the ROI (the loop's step 0 gives the init frame again)."""
        if self._first:
            self._first = False
            note = contract_note(track.corners, self.corners0)
            if note is not None and self.contract_note is None:
                self.contract_note = f"tracker {self.name!r}: {note}"
                warnings.warn(self.contract_note, ContractWarning, stacklevel=3)
        return track

    def _track(self, out, ms: float):
        from hvs_sim.tracking.base import MODES, Track
        from hvs_sim.tracking.warp import fit_similarity, matrix_to_pose

        who = f"tracker {self.name!r}"
        if out is None:
            raise PluginFault(f"{who} returned None; accepted: a Track or an object/mapping with corners (4×2 pixels)")
        try:
            corners = np.asarray(_field(out, "corners"), float)
        except (TypeError, ValueError):
            corners = np.zeros(0)
        if corners.shape != (4, 2) or not np.all(np.isfinite(corners)):
            raise PluginFault(f"{who} returned corners of shape {corners.shape}"
                              + ("" if corners.shape != (4, 2) else " with non-finite values")
                              + "; accepted: 4×2 finite pixels")
        center = _field(out, "center")
        try:
            center = corners.mean(0) if center is None else np.asarray(center, float).reshape(-1)
        except (TypeError, ValueError):
            center = np.full(1, np.nan)
        mode = str(_field(out, "mode", "align"))
        values = {k: _field(out, k, d) for k, d in (("occlusion", 0.0), ("score", 1.0), ("confidence", 1.0))}
        if center.shape != (2,) or not np.all(np.isfinite(center)):
            raise PluginFault(f"{who} returned a centre {center.tolist()}; accepted: 2 finite pixels")
        if mode not in MODES:
            raise PluginFault(f"{who} returned mode {mode!r}; accepted: {', '.join(MODES)}")
        for k, v in values.items():
            try:
                v = float(v)
            except (TypeError, ValueError):
                v = float("nan")
            if not (np.isfinite(v) and (k == "score" or 0.0 <= v <= 1.0)):
                raise PluginFault(f"{who} returned {k} {values[k]!r}; accepted: a finite number"
                                  + ("" if k == "score" else " in [0, 1]"))
            values[k] = v
        pose = matrix_to_pose(fit_similarity(self.corners0, corners), self.corners0.mean(0))
        return Track(center=center, corners=corners, pose=pose, mode=mode, occlusion=values["occlusion"],
                     score=values["score"], ms=ms, confidence=values["confidence"])


class ExternalController:
    """An outside servo law: compute(ControlInput) checked to a finite 6-vector and valid DOFs."""

    def __init__(self, inner, name: str):
        from hvs_sim.control.protocol import check_dofs

        self.inner, self.name = inner, name
        dofs = getattr(inner, "dofs", None)
        try:
            self.dofs = None if dofs is None else check_dofs(dofs, f"controller {name!r}")
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        self.uses_features = bool(getattr(inner, "uses_features", True))

    def compute(self, inp):
        from hvs_sim.control.protocol import check_dofs, check_twist

        who = f"controller {self.name!r}"
        out = self.inner.compute(inp)
        twist = check_twist(out, who)
        dofs = getattr(out, "dofs", None) or self.dofs
        return twist, None if dofs is None else check_dofs(dofs, who)


class ExternalPolicy:
    """An outside policy: act(PolicyInput) checked to a finite 6-vector."""

    def __init__(self, inner, name: str):
        from hvs_sim.control.protocol import DOF_NAMES, check_dofs

        self.inner, self.name = inner, name
        try:
            self.dofs = check_dofs(getattr(inner, "dofs", DOF_NAMES), f"policy {name!r}")
        except ValueError as exc:
            raise ConfigError(str(exc)) from None

    def reset(self, obs) -> None:
        if callable(getattr(self.inner, "reset", None)):
            self.inner.reset(obs)

    def act(self, obs) -> np.ndarray:
        from hvs_sim.control.protocol import check_twist

        return check_twist(self.inner.act(obs), f"policy {self.name!r}")


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
