"""YAML scenario -> validated :class:`Scenario` (pydantic, unknown fields rejected).

A scenario picks the components (plugin, params, input wiring), the path,
the duration, the step and the seed, and optionally a sweep. Errors name the
field and the YAML line. Overrides (``--set a.b.c=value``) and sweep axes use
the same dotted paths into the YAML document.
"""

from __future__ import annotations

import difflib
import functools
import itertools
import json
import re
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from cosim.contract.errors import ScenarioError
from cosim.contract.params import IDEAL
from cosim.contract.plugins import load_plugin_file, registry
from cosim.contract.views import view_roles

#: Names no component may take: the bus keys its own messages under them (``cosim/<run>/alive``, ``.../ctl``).
RESERVED_NAMES = ("alive", "ctl")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", populate_by_name=True)


#: The longest delay an input wire may have [ticks]: each producer keeps this many rows more.
MAX_DELAY_TICKS = 16


class InputSpec(_Strict):
    """One input wire: ``from: component.port``; ``delay: N`` reads the value of N ticks before
    (``delay: 1`` breaks a cycle: the previous tick's value); at most ``MAX_DELAY_TICKS``."""

    source: str = Field(alias="from", pattern=r"^[A-Za-z_][\w-]*\.[A-Za-z_]\w*$")
    delay: int = Field(0, ge=0, le=MAX_DELAY_TICKS)

    @property
    def component(self) -> str:
        return self.source.split(".", 1)[0]

    @property
    def port(self) -> str:
        return self.source.split(".", 1)[1]


class ComponentSpec(_Strict):
    """One component of a scenario: its plugin, parameters, input wires, period and timeout."""
    plugin: str = Field(description="registered component name, see `cosim plugins`")
    params: dict[str, Any] = Field(default_factory=dict)
    inputs: dict[str, InputSpec] = Field(default_factory=dict)
    period: int = Field(1, ge=1, description="update period in multiples of dt_s")
    timeout_s: float | None = Field(None, gt=0, description="per-step timeout; default: the scenario's")

    @field_validator("inputs", mode="before")
    @classmethod
    def _shorthand(cls, value):
        if isinstance(value, dict):
            return {k: ({"from": v} if isinstance(v, str) else v) for k, v in value.items()}
        return value


class PathSpec(_Strict):
    """The scenario's reference path: a registered path plugin and its parameters."""
    plugin: str
    params: dict[str, Any] = Field(default_factory=dict)


class RecordSpec(_Strict):
    """Which ports play which role in the summary and the recording.

    ``truth`` is the tracking-error reference (its distance to the path);
    ``measured`` and ``estimate`` are what the sensor and the estimator made of
    it. Any role may be null. Their default ports are the domain's (hook
    ``cosim_default_roles``; none: unbound). The domain's views (hook
    ``cosim_register_views``) read roles of their own, with defaults they give;
    a scenario binds them here too, by the same ``role: component.port``.
    """

    model_config = ConfigDict(extra="allow")

    measured: str | None = None
    truth: str | None = None
    estimate: str | None = None
    solve_time: str | None = None
    #: Measurement minus the estimator's prediction at each frame (NaN between frames).
    prediction_error: str | None = None
    #: When each measurement was captured [s] (a sensor that has no such port: at delivery).
    capture_time: str | None = None

    @model_validator(mode="after")
    def _known_roles(self):
        extra = set(self.model_extra or {})
        known = view_roles()
        unknown = sorted(extra - set(known))
        if unknown:
            listing = ", ".join(sorted({*type(self).model_fields, *known}))
            raise ValueError(f"unknown role {unknown[0]!r}; the roles are {listing}")
        for role, port in (self.model_extra or {}).items():
            if port is not None and not (isinstance(port, str) and "." in port):
                raise ValueError(f"{role}: expected component.port or null, got {port!r}")
        return self

    def ports(self) -> dict[str, str | None]:
        """Every role's port: the domain's defaults (:func:`cosim.contract.views.view_roles`), then
        this scenario's bindings."""
        return {**dict.fromkeys(type(self).model_fields), **view_roles(), **self.model_dump(exclude_unset=True)}


class ReportSpec(_Strict):
    """What a sweep's summary says about one figure of its runs (:mod:`cosim.record.sweep_report`):
    pooled over seeds, a plot per numeric axis and, with a threshold, the largest axis values below it."""

    figure: str | None = Field(None, min_length=1, description=(
        "the run figure the sweep reports on, a key of a run's summary.json (its unit the key's "
        "suffix, e.g. _mm, _rad_s); default: the tracking error when the runs have a path"))
    part: str | None = Field(None, min_length=1, description=(
        "the part of a figure that has parts to read (e.g. rms of speed_error_rad_s); default: its mean"))
    threshold: float | None = Field(None, description=(
        "with figure: report, per group of the other labels, the largest value of each numeric "
        "sweep axis at which the figure (its mean over the seeds) stays below this, in its unit"))

    @model_validator(mode="before")
    @classmethod
    def _renamed(cls, data: Any) -> Any:
        if isinstance(data, dict) and "threshold_mm" in data:
            raise ValueError(
                "threshold_mm is no longer read: name the figure and its threshold, e.g. "
                f"report: {{figure: tracking_error_mm, threshold: {data['threshold_mm']}}}")
        return data

    @model_validator(mode="after")
    def _figure_named(self):
        if (self.threshold is not None or self.part is not None) and not self.figure:
            raise ValueError("threshold and part need the figure they apply to: "
                             "report: {figure: KEY, threshold: VALUE}")
        return self


#: A scenario's name: it names the run's folder (``runs/NAME``), so a plain name, no path.
PLAIN_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$")


class Scenario(_Strict):
    """A validated scenario (see the module docstring and ``cosim schema``)."""

    name: str = Field(description="a plain name (letters, digits, '.', '_', '-'): it names the run's folder")
    description: str = ""
    duration_s: float | None = Field(gt=0, description=(
        "simulated time to run [s]; null: run until stopped (Ctrl-C, SIGTERM, a fault or the end of "
        "a replayed input)"))
    dt_s: float = Field(0.02, gt=0, le=1.0)
    seed: int = 0
    profile: str = Field("ideal", description=(
        "the parameter set of the components' physical and sensor effects: a profile a plugin registers "
        "(see `cosim plugins`); its values are set before the file's --set overrides and sweep axes"))
    plugins: list[str] = Field(default_factory=list,
                               description="Python plugin files to load, relative to the scenario file")
    timeout_s: float = Field(30.0, gt=0, description="default per-step timeout of every component")
    realtime: float | None = Field(None, gt=0, description=(
        "pace the ticks on the wall clock at this factor of real time (1: real time, as against "
        "hardware); late ticks are skipped and counted; none: as fast as possible"))
    path: PathSpec | None = None
    components: dict[str, ComponentSpec]
    record: RecordSpec = Field(default_factory=RecordSpec)
    sweep: dict[str, list[Any]] = Field(default_factory=dict)
    report: ReportSpec = Field(default_factory=ReportSpec)

    @field_validator("name")
    @classmethod
    def _plain_name(cls, name: str) -> str:
        if not PLAIN_NAME.match(name) or ".." in name:
            raise ValueError(f"{name!r} is not a plain name: use letters, digits, '.', '_' and '-' (up to 100, "
                             "no '..'); it names the run's folder under runs/, so it cannot be a path")
        return name

    @model_validator(mode="after")
    def _check_wiring(self):
        for name, comp in self.components.items():
            if name in RESERVED_NAMES or not name.replace("_", "a").replace("-", "a").isalnum():
                raise ValueError(f"component name {name!r} is reserved or not a plain word")
            for port, wire in comp.inputs.items():
                if wire.component not in self.components:
                    raise ValueError(
                        f"components.{name}.inputs.{port}: source component {wire.component!r} "
                        f"is not in the scenario (have: {', '.join(self.components)})"
                    )
        for axis, values in self.sweep.items():
            if not values:
                raise ValueError(f"sweep.{axis}: needs at least one value")
        return self

    @property
    def n_steps(self) -> int | None:
        """Ticks to run; None for a run until stopped (``duration_s: null``)."""
        return None if self.duration_s is None else int(round(self.duration_s / self.dt_s))

    @property
    def recording_id(self) -> str:
        """The id every file of a run's rerun recording shares (the viewer merges files by it)."""
        return self.name


# ---------------------------------------------------------------- loading


class _Loader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):
    """libyaml's parser where PyYAML has it (a sweep reads its scenario once per run: ~10x
    faster), reading ``5e-8`` and ``1E3`` as numbers as YAML 1.2 does (YAML 1.1 wants a dot
    and a signed exponent, ``5.0e-8``, and reads ``5e-8`` as a string)."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"))


class YamlDocument:
    """A YAML file's text, whose node tree (for the line of a field) is composed only when asked."""

    def __init__(self, text: str):
        self.text = text

    @functools.cached_property
    def node(self) -> yaml.Node | None:
        return yaml.compose(self.text, Loader=_Loader)


def load_document(path: str | Path, what: str = "scenario") -> tuple[dict, YamlDocument]:
    """Read a YAML file (a ``what``: scenario, hosts file) as ``(data, document)``; syntax errors
    name the line."""
    path = Path(path)
    if not path.is_file():
        raise ScenarioError(f"{what} file {path} does not exist" if what == "scenario" else
                            f"{what} {path} does not exist")
    text = path.read_text()
    try:
        data = yaml.load(text, Loader=_Loader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" line {mark.line + 1}" if mark else ""
        raise ScenarioError(f"{path}{where}: not valid YAML: {getattr(exc, 'problem', exc)}") from None
    if not isinstance(data, dict):
        raise ScenarioError(f"{path}: a {what} is a YAML mapping, got {type(data).__name__}")
    return data, YamlDocument(text)


def load_scenario(path: str | Path, overrides: list[str] | tuple[str, ...] = ()) -> Scenario:
    """Load, apply ``key=value`` overrides, validate. Errors name field and line."""
    data, node = load_document(path)
    parsed = [parse_override(item) for item in overrides]
    check_override_components(data, parsed, overrides)
    for key, value in parsed:
        set_dotted(data, key, value)
    # its plugin files first: they may register the profile, the recorded roles, the components it names
    files = data.get("plugins")
    load_scenario_plugins(files if isinstance(files, list) else [], Path(path).parent)
    apply_profile(data, data.get("profile", "ideal"), source=str(path), explicit=_explicit_params(parsed))
    return validate(data, source=str(path), node=node, overrides=dict(zip((k for k, _ in parsed), overrides)))


def check_override_components(data: dict, parsed: list[tuple[str, Any]], items) -> None:
    """An override reaching into a component the scenario does not have (``components.camra.params.x``)
    is a typo in the flag: say so, naming the flag, rather than let the new half-component fail
    validation as if the file were wrong. Setting a whole new component (``components.NAME={...}``)
    stays allowed."""
    have = data.get("components") if isinstance(data.get("components"), dict) else {}
    added = {key.split(".")[1] for key, _ in parsed if key.count(".") == 1 and key.startswith("components.")}
    for (key, _), item in zip(parsed, items):
        parts = key.split(".")
        if len(parts) > 2 and parts[0] == "components" and parts[1] not in have and parts[1] not in added:
            close = difflib.get_close_matches(parts[1], list(have), n=1)
            hint = f"; did you mean {close[0]}?" if close else ""
            raise ScenarioError(f"--set {item}: no component {parts[1]!r} in the scenario "
                                f"(have: {', '.join(have) or 'none'}){hint}")


def _explicit_params(parsed: list[tuple[str, Any]]) -> dict[str, set[str]]:
    """Per component, the parameters ``--set`` overrides (and sweep axes) name: a profile leaves them."""
    out: dict[str, set[str]] = {}
    for key, value in parsed:
        parts = key.split(".")
        if len(parts) >= 3 and parts[0] == "components" and parts[2] == "params":
            names = out.setdefault(parts[1], set())
            if len(parts) > 3:
                names.add(parts[3])
            elif isinstance(value, dict):
                names.update(value)
        elif len(parts) == 2 and parts[0] == "components" and isinstance(value, dict):
            out.setdefault(parts[1], set()).update(value.get("params") or {})
    return out


def apply_profile(data: dict, name: Any, source: str = "<scenario>",
                  explicit: dict[str, set[str]] | None = None) -> None:
    """Set the parameters profile ``name`` gives each component by its plugin (``ideal``: none).

    A profile (registered by a plugin, :func:`cosim.contract.plugins.registry` ``("profile")``) is
    ``{plugin name: {param: value}}``; the values land in ``components.NAME.params`` of every
    component using that plugin (after the overrides, so a sweep axis that swaps the plugin gets
    the new plugin's), replacing the file's values but not those an override names (``explicit``:
    ``{component: {param, ...}}``): ``--set`` and sweep axes win over the profile.
    """
    explicit = explicit or {}
    values = profile_values(name, source)
    for cname, comp in (data.get("components") or {}).items():
        if isinstance(comp, dict) and comp.get("plugin") in values:
            params = comp.get("params") or {}
            keep = explicit.get(cname, set())
            comp["params"] = {**params, **{k: v for k, v in values[comp["plugin"]].items() if k not in keep}}
    data["profile"] = name


def profile_values(name: Any, source: str = "<scenario>") -> dict:
    """The values profile ``name`` sets, ``{plugin name: {param: value}}`` (``ideal``, unless a plugin
    registers it: none); an unknown profile raises :class:`ScenarioError` naming ``source``."""
    profiles = registry("profile")
    if name == "ideal" and name not in profiles:
        return IDEAL
    if name not in profiles:
        raise ScenarioError(f"{source}: profile {name!r} unknown; known: {', '.join(['ideal', *sorted(profiles)])}")
    return profiles[name]


def load_scenario_plugins(files: list, base_dir: Path) -> None:
    """Register a scenario's own plugin ``files`` (paths relative to ``base_dir``; what is not a
    string is left to the scenario's validation to report)."""
    for item in files:
        if not isinstance(item, str):
            continue
        file = Path(item) if Path(item).is_absolute() else base_dir / item
        load_plugin_file(file)


def validate(data: dict, source: str = "<scenario>", node: YamlDocument | yaml.Node | None = None,
             overrides: dict[str, str] | None = None) -> Scenario:
    """The validated scenario; errors name each field and its YAML line, or the ``--set`` flag that
    wrote it (``overrides``: ``{dotted key: the flag's KEY=VALUE}``)."""
    try:
        return Scenario.model_validate(data)
    except ValidationError as exc:
        lines = error_lines(exc, node, overrides)
        if lines and all("(--set " in line for line in lines):
            raise ScenarioError(f"invalid --set for {source}\n" + "\n".join(lines)) from None
        raise ScenarioError(f"{source}: invalid scenario\n" + "\n".join(lines)) from None


def error_lines(exc: ValidationError, node: YamlDocument | yaml.Node | None,
                overrides: dict[str, str] | None = None) -> list[str]:
    """One line per error of a pydantic validation: the field's dotted path, its YAML line (or the
    ``--set`` flag that set it), what is wrong."""
    lines = []
    for err in exc.errors():
        loc = [str(p) for p in err["loc"]]
        field = ".".join(loc) or "(top level)"
        flag = next((item for key, item in (overrides or {}).items()
                     if field == key or field.startswith(key + ".")), None)
        line = None if flag else line_of(node, err["loc"])
        where = f" (--set {flag})" if flag else f" (line {line})" if line else ""
        msg = "unknown field" if err["type"] == "extra_forbidden" else err["msg"]
        lines.append(f"  {field}{where}: {msg}")
    return lines


def line_of(node: YamlDocument | yaml.Node | None, loc) -> int | None:
    """1-based line of the deepest YAML node on the path ``loc``."""
    if isinstance(node, YamlDocument):
        node = node.node
    line = None
    for key in loc:
        if isinstance(node, yaml.MappingNode):
            for k, v in node.value:
                if k.value == str(key):
                    line = k.start_mark.line + 1
                    node = v
                    break
            else:
                return line
        elif isinstance(node, yaml.SequenceNode) and isinstance(key, int) and key < len(node.value):
            node = node.value[key]
            line = node.start_mark.line + 1
        else:
            return line
    return line


# ---------------------------------------------------------------- overrides and sweeps


def parse_override(item: str) -> tuple[str, Any]:
    """``KEY=VALUE`` (``--set``) as ``(dotted key, value)``, the value read as YAML."""
    if "=" not in item:
        raise ScenarioError(f"--set {item!r}: expected key=value, e.g. components.NAME.params.PARAM=VALUE")
    key, raw = item.split("=", 1)
    try:
        value = yaml.load(raw, Loader=_Loader) if raw else None
    except yaml.YAMLError:
        value = raw
    return key.strip(), value


def set_dotted(data: dict, key: str, value: Any) -> None:
    """Set ``data[a][b][c] = value`` for ``key = 'a.b.c'``, creating mappings as needed."""
    parts = key.split(".")
    cur = data
    for i, part in enumerate(parts[:-1]):
        nxt = cur.get(part) if isinstance(cur, dict) else None
        if nxt is None:
            nxt = cur[part] = {}
        if not isinstance(nxt, dict):
            raise ScenarioError(f"cannot set {key!r}: {'.'.join(parts[: i + 1])} is not a mapping")
        cur = nxt
    cur[parts[-1]] = value


#: top-level fields a sweep axis may name plainly (``seed: [1, 2, 3]`` repeats every run over seeds)
TOP_LEVEL_AXES = ("seed", "profile", "duration_s")


def sweep_overrides(scenario: Scenario) -> list[tuple[dict[str, Any], list[str]]]:
    """One ``(labels, overrides)`` per combination of the sweep axes (product order).

    An axis named by a dotted path (``components.controller.params.kp``)
    sets that field; its label is the last part (``kp``); so does an
    axis named by a top-level field (``seed``, ``profile``: :data:`TOP_LEVEL_AXES`). An axis with
    a plain name (``variant``) lists mappings of dotted paths to values,
    each with an optional ``label`` (default: the first value) and any other
    plain keys as further labels (``model: linear``).
    Overrides are ``key=value`` strings as ``--set`` takes them.
    """
    axes = list(scenario.sweep.items())
    out = []
    for combo in itertools.product(*[values for _, values in axes]):
        labels: dict[str, Any] = {}
        overrides: list[str] = []
        for axis, value in zip(axes, combo):
            axis = axis[0]
            if "." in axis or (axis in TOP_LEVEL_AXES and not isinstance(value, dict)):
                overrides.append(f"{axis}={json.dumps(value)}")
                labels[axis.rsplit(".", 1)[-1]] = value
                continue
            if not isinstance(value, dict):
                raise ScenarioError(f"sweep.{axis}: each value must be a mapping of dotted keys to values")
            value = dict(value)
            label = value.pop("label", None)
            for k, v in value.items():
                if "." in k:
                    overrides.append(f"{k}={json.dumps(v)}")
                    label = v if label is None else label
                else:  # a plain key is one more label of this run (e.g. model: physical)
                    labels[k] = v
            labels[axis] = label
        out.append((labels, overrides))
    return out


def json_schema() -> dict:
    """JSON Schema of the scenario format (for editors)."""
    return Scenario.model_json_schema(by_alias=True)
