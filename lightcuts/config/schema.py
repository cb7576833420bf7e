"""The run config: one YAML file describes scene, camera, lights, tree, render and output.

Validated with pydantic (``extra="forbid"``: an unknown key is an error, not a silent typo). Every
error becomes one line ``<file>: <dotted.key>: <problem>``. Relative file paths are resolved against
the config file's folder and checked before any work starts.
"""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

import yaml
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from lightcuts.errors import LightcutsError
from lightcuts.limits import (MAX_BOUNCES, MAX_CONTINUATION_RAYS, MAX_COORD, MAX_CUT, MAX_EMITTER_TRIANGLES,
                              MAX_EXPOSURE, MAX_LIGHTS, MAX_PASSES, MAX_PIXELS, MAX_SEED, MAX_SPP)

#: Run defaults, here alone: commands and stage APIs read them from this module.
DEFAULT_BUILDER = "agglomerative"
#: The metric of builders that read one, when the config names none.
DEFAULT_METRIC = "walter2008"
DEFAULT_EPS = 0.02
DEFAULT_MAX_CUT = 1000
#: The VPLs the default clamp's disc holds (render.clamp.vpls; docs/math.md, "Clamping").
DEFAULT_CLAMP_VPLS = 400
#: The density clamp's disc covers at most 1 / LIT_AREA_SHARES of the lit surfaces (of the VPLs).
LIT_AREA_SHARES = 250
DEFAULT_RAY_CASTER = "embree"
DEFAULT_INTEGRATOR = "lightcuts"

#: A number the kernels can square and sum without overflow (lightcuts.limits.MAX_COORD).
Num = Annotated[float, Field(ge=-MAX_COORD, le=MAX_COORD)]
Vec3 = Annotated[list[Num], Field(min_length=3, max_length=3)]
PositiveInt = Annotated[int, Field(ge=1)]
#: A number of lights (lightcuts.limits.MAX_LIGHTS: memory).
LightCount = Annotated[int, Field(ge=0, le=MAX_LIGHTS)]
#: (width, height) pixels, at most MAX_PIXELS in all: checked before any buffer is allocated.
Resolution = Annotated[list[PositiveInt], Field(min_length=2, max_length=2)]


def _check_pixels(v):
    if v is not None and v[0] * v[1] > MAX_PIXELS:
        raise ValueError(f"{v[0]} x {v[1]} is more than {MAX_PIXELS:,} pixels")
    return v


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", validate_default=True, allow_inf_nan=False)


class Material(Strict):
    """Per-mesh material override (triangle ids inherit it)."""

    albedo: Vec3 = [0.5, 0.5, 0.5]
    specular: Vec3 = [0.0, 0.0, 0.0]
    exponent: Annotated[float, Field(ge=0, le=MAX_COORD)] = 0.0
    emission: Vec3 = [0.0, 0.0, 0.0]

    @field_validator("albedo", "specular", "emission")
    @classmethod
    def _non_negative(cls, v):
        if any(x < 0 for x in v):
            raise ValueError("values must be >= 0")
        return v


class Transform(Strict):
    """Applied as scale, then rotate (Euler XYZ, degrees), then translate."""

    scale: Num | Vec3 = 1.0
    rotate: Vec3 = [0.0, 0.0, 0.0]
    translate: Vec3 = [0.0, 0.0, 0.0]


class MeshEntry(Transform):
    file: str
    material: Material | None = None


def _plugin_shape(v):
    """A plugin named as ``NAME`` or ``{type: NAME, param: value, ...}``: only the shape is checked
    here; the plan step resolves the name and its parameters through the plugin's registry."""
    if isinstance(v, dict):
        if not isinstance(v.get("type"), str):
            raise ValueError("a mapping needs 'type' (a name)")
    elif not isinstance(v, str):
        raise ValueError(f"expected a name or a {{type: NAME, ...}} mapping, got {v!r}")
    return v


#: A plugin as a config names it (:func:`_plugin_shape`).
PluginSpec = Annotated[Any, AfterValidator(_plugin_shape)]


class EmitterGrid(Strict):
    """Emitters at the centres of a ``count`` = [nx, ny, nz] grid of cells over the box [lo, hi]
    (an axis with lo = hi takes count 1: e.g. lamps in a plane below a ceiling)."""

    lo: Vec3
    hi: Vec3
    count: Annotated[list[Annotated[int, Field(ge=1, le=1024)]], Field(min_length=3, max_length=3)]

    @field_validator("hi")
    @classmethod
    def _ordered(cls, v, info):
        lo = info.data.get("lo")
        if lo is not None and any(h < lo_ for h, lo_ in zip(v, lo)):
            raise ValueError("must be >= lo on every axis")
        return v


class AreaLight(Strict):
    """An emitter placed by the config (``scene.emitters``): a ``quad`` of ``size`` [w, h] or a
    ``disc`` of ``radius`` (a fan of ``segments`` triangles), centred at ``position`` or at every
    cell centre of ``grid``, emitting ``radiance`` (W/(m^2 sr), RGB) on the side of ``normal``; a
    quad's w runs along ``normal x up`` (default up: whichever of +y, +z is less parallel to the
    normal). The triangles join the scene as emitters of albedo ``albedo`` (default 0: black)."""

    shape: Literal["quad", "disc"] = "quad"
    position: Vec3 | None = None
    grid: EmitterGrid | None = None
    normal: Vec3
    up: Vec3 | None = None
    size: Annotated[list[Annotated[float, Field(gt=0, le=MAX_COORD)]], Field(min_length=2, max_length=2)] | None = None
    radius: Annotated[float, Field(gt=0, le=MAX_COORD)] | None = None
    segments: Annotated[int, Field(ge=3, le=1024)] = 32
    radiance: Vec3
    albedo: Vec3 = [0.0, 0.0, 0.0]

    @field_validator("radiance", "albedo")
    @classmethod
    def _non_negative(cls, v):
        if any(x < 0 for x in v):
            raise ValueError("values must be >= 0")
        return v

    @model_validator(mode="after")
    def _complete(self):
        if (self.position is None) == (self.grid is None):
            raise ValueError("give exactly one of position and grid")
        if self.shape == "quad" and (self.size is None or self.radius is not None):
            raise ValueError("a quad takes size: [w, h] (and no radius)")
        if self.shape == "disc" and (self.radius is None or self.size is not None):
            raise ValueError("a disc takes radius (and no size)")
        if not any(self.normal):
            raise ValueError("normal: must not be zero")
        if self.up is not None:
            n, u = self.normal, self.up
            c = (n[1] * u[2] - n[2] * u[1], n[2] * u[0] - n[0] * u[2], n[0] * u[1] - n[1] * u[0])
            if sum(x * x for x in c) <= 1e-18 * sum(x * x for x in n) * sum(x * x for x in u):
                raise ValueError("up: zero or parallel to the normal")
        if not any(self.radiance):
            raise ValueError("radiance: must not be all zero")
        return self

    def triangles(self) -> int:
        """The triangles this entry adds: per emitter 2 (quad) or ``segments`` (disc), times the
        grid's cells."""
        cells = 1 if self.grid is None else self.grid.count[0] * self.grid.count[1] * self.grid.count[2]
        return cells * (2 if self.shape == "quad" else self.segments)


class SceneConfig(Strict):
    """``builtin: cornell`` or ``procedural: {type: kitchen, triangles: ...}``, and/or a list of mesh
    files (OBJ with MTL, PLY, glTF/GLB); a ``procedural: {type: gallery}`` places the meshes on
    plinths. The scene types and their parameters are entries of ``lightcuts.scene.registry.SCENES``,
    resolved in the plan step."""

    builtin: str | None = None
    procedural: PluginSpec | None = None
    # A Mitsuba 3 XML scene read through Mitsuba's parser (lightcuts.scene.mitsuba_xml).
    mitsuba: str | None = None
    meshes: list[MeshEntry] = []
    # Optional material override of named built-in surfaces (e.g. floor, short_block, tall_block).
    materials: dict[str, Material] = {}
    # Area lights placed by the config (quads, discs, grids of them), added as emitting triangles.
    emitters: list[AreaLight] = []

    @field_validator("emitters")
    @classmethod
    def _emitter_triangles(cls, v):
        n = sum(e.triangles() for e in v)
        if n > MAX_EMITTER_TRIANGLES:
            raise ValueError(f"{n:,} triangles in all (grid cells x triangles per emitter), more than "
                             f"{MAX_EMITTER_TRIANGLES:,} (lightcuts.limits.MAX_EMITTER_TRIANGLES)")
        return v


class CameraConfig(Strict):
    position: Vec3 | None = None
    look_at: Vec3 | None = None
    up: Vec3 | None = None
    fov: Annotated[float, Field(gt=0, lt=180)] | None = None
    resolution: Resolution | None = None
    # Thin lens (render.integrator multidimensional): lens radius, world units (0: pinhole), and the
    # distance along the view direction that is in focus (None: |look_at - position|).
    aperture: Annotated[float, Field(ge=0, le=MAX_COORD)] = 0.0
    focus_distance: Annotated[float, Field(gt=0, le=MAX_COORD)] | None = None

    @field_validator("resolution")
    @classmethod
    def _pixels(cls, v):
        return _check_pixels(v)


class DirectLights(Strict):
    """Direct light from the emitting triangles: ``source: samples`` places ``count`` oriented lights
    on them (area-weighted, stratified); ``source: triangles`` makes every emitting triangle one light
    (``count`` is then not read), which an integrator with the ``triangle_lights`` trait samples a
    point of per shading point (lightcuts.lights.triangles)."""

    count: LightCount = 1024
    source: Literal["samples", "triangles"] = "samples"


class IndirectLights(Strict):
    """Particle tracing from the emitters: about ``count`` VPLs stored at diffuse bounces."""

    count: LightCount = 0
    max_bounces: Annotated[int, Field(ge=1, le=MAX_BOUNCES)] = 16
    # Russian roulette starts after this many bounces, survival probability = min(1, max albedo).
    rr_start: Annotated[int, Field(ge=0)] = 1


class Sun(Strict):
    direction: Vec3  # towards the sun
    irradiance: Vec3  # W/m^2 at normal incidence, RGB

    @field_validator("irradiance")
    @classmethod
    def _lit(cls, v):
        if any(x < 0 for x in v):
            raise ValueError("values must be >= 0")
        if not any(x > 0 for x in v):
            raise ValueError("is zero: the sun gives no light (remove lights.sun)")
        return v


class Procedural(Strict):
    """A sky generated by lightcuts (nothing to download): a lat-long HDR map."""

    type: Literal["sky"] = "sky"
    sun_direction: Vec3 = [0.3, 1.0, 0.2]
    resolution: Resolution = [256, 128]
    zenith: Vec3 = [0.25, 0.45, 1.0]
    horizon: Vec3 = [0.9, 0.95, 1.0]
    ground: Vec3 = [0.15, 0.13, 0.11]
    # A sun disc inside the map (W/m^2 at normal incidence; 0 = none, e.g. when lights.sun is set).
    sun_irradiance: Annotated[float, Field(ge=0, le=MAX_COORD)] = 15.0
    sun_radius: Annotated[float, Field(gt=0, le=45)] = 2.0  # degrees

    @field_validator("resolution")
    @classmethod
    def _pixels(cls, v):
        return _check_pixels(v)


class Environment(Strict):
    """An HDR lat-long environment map (EXR file, or generated; neither: the ``constant`` or ``envmap``
    emitter of the ``scene.mitsuba`` file) sampled into ``count`` directional lights."""

    file: str | None = None
    procedural: Procedural | None = None
    count: Annotated[int, Field(ge=1, le=MAX_LIGHTS)] = 1024
    scale: Annotated[float, Field(gt=0, le=MAX_COORD)] = 1.0
    # Rotation of the map about +y, degrees.
    rotate: Num = 0.0


class LightsConfig(Strict):
    direct: DirectLights = DirectLights()
    indirect: IndirectLights = IndirectLights()
    sun: Sun | None = None
    environment: Environment | None = None

    @model_validator(mode="after")
    def _total(self):
        env = self.environment.count if self.environment is not None else 0
        n = self.direct.count + self.indirect.count + env
        if n > MAX_LIGHTS:
            raise ValueError(f"direct.count {self.direct.count:,} + indirect.count {self.indirect.count:,} + "
                             f"environment.count {env:,} = {n:,} lights, more than {MAX_LIGHTS:,} "
                             "(lightcuts.limits.MAX_LIGHTS)")
        return self


class TreeConfig(Strict):
    """The builder and the parameters it reads, as ``builder: NAME`` with flat ``metric`` and ``c``, or
    ``builder: {type: NAME, metric: ..., c: ...}``; ``metric`` and ``c`` only for builders that read
    them (``lightcuts.trees.spec``): None gives DEFAULT_METRIC and the scene diagonal / 16."""

    builder: PluginSpec = DEFAULT_BUILDER
    metric: str | None = None
    c: Annotated[float, Field(gt=0, le=MAX_COORD)] | None = None


class Clamp(Strict):
    """Clamping of indirect VPLs: G uses max(d, r) (docs/math.md, "Clamping"). ``mode: density`` (the
    default): r = sqrt(min(vpls, N / LIT_AREA_SHARES)) * the N indirect VPLs' median spacing
    (lightcuts.lights.spacing), the radius of a disc holding about ``vpls`` VPLs and at most
    1 / LIT_AREA_SHARES of them; ``mode: diagonal``: r = min_distance * scene diagonal. A config that
    sets ``min_distance`` without a mode means ``diagonal``."""

    enabled: bool = True
    mode: Literal["density", "diagonal"] = "density"
    vpls: Annotated[float, Field(ge=0, le=MAX_LIGHTS)] = DEFAULT_CLAMP_VPLS
    min_distance: Annotated[float, Field(ge=0, le=MAX_COORD)] = 0.05

    @model_validator(mode="before")
    @classmethod
    def _mode_from_keys(cls, v):
        if isinstance(v, dict) and "mode" not in v:
            if "min_distance" in v and "vpls" in v:
                raise ValueError("min_distance is mode diagonal's, vpls mode density's: set mode, or one of them")
            if "min_distance" in v:
                return {**v, "mode": "diagonal"}
        return v

    @model_validator(mode="after")
    def _keys_of_mode(self):
        other = {"density": "min_distance", "diagonal": "vpls"}[self.mode]
        if other in self.model_fields_set:
            raise ValueError(f"{other}: not read in mode {self.mode}")
        return self


class ToneMap(Strict):
    """How the PNGs and the HTML report's viewer show the linear image: an operator of
    lightcuts.report.tonemap.OPERATORS after ``exposure`` stops; a bare name means that operator at 0 stops."""

    type: Literal["clip", "reinhard", "aces", "hable"] = "clip"
    # Stops; 2**exposure must be a normal float64.
    exposure: Annotated[float, Field(ge=-MAX_EXPOSURE, le=MAX_EXPOSURE)] = 0.0

    @model_validator(mode="before")
    @classmethod
    def _name(cls, v):
        return {"type": v} if isinstance(v, str) else v


class RenderConfig(Strict):
    # Eye rays per pixel (multidimensional: gather points), at most MAX_SPP (per-thread scratch, time).
    spp: Annotated[int, Field(ge=1, le=MAX_SPP)] = 1
    # Relative error bound: 1 already accepts any cluster whose bound is below the total estimate.
    eps: Annotated[float, Field(gt=0, le=1)] = DEFAULT_EPS
    max_cut: Annotated[int, Field(ge=1, le=MAX_CUT)] = DEFAULT_MAX_CUT
    clamp: Clamp = Clamp()
    # The PNGs' and the report viewer's tone map (the EXR is linear): a name or {type: NAME, exposure: STOPS}.
    tonemap: ToneMap = ToneMap()

    @model_validator(mode="before")
    @classmethod
    def _exposure_moved(cls, v):
        if isinstance(v, dict) and "exposure" in v:
            raise ValueError("exposure: set render.tonemap.exposure (render.tonemap: {type: clip, exposure: STOPS})")
        return v

    # A caster name, or {type: NAME, param: value, ...}; resolved and checked by the plan step
    # (lightcuts.accel.registry.RAY_CASTERS declares each caster's parameters).
    ray_caster: PluginSpec = DEFAULT_RAY_CASTER
    # How each pixel is computed: a name or {type: NAME, ...} of lightcuts.integrators.registry.INTEGRATORS.
    integrator: PluginSpec = DEFAULT_INTEGRATOR
    # Render only the window [x0, y0, x1, y1) of the image (pixels), e.g. for reference checks.
    crop: Annotated[list[int], Field(min_length=4, max_length=4)] | None = None
    # The light that VPLs lose (docs/math.md, "Converging images"): the part clamping removes and the part
    # glossy surfaces reflect, carried by a continuation of the eye path (integrator lightcuts).
    compensation: bool = False
    # With compensation: the continuations averaged per eye ray (less noise in that light per cut).
    continuation_rays: Annotated[int, Field(ge=1, le=MAX_CONTINUATION_RAYS)] = 1
    # A cut node's representative: the tree's (fixed, Lightcuts 2005) or one drawn per shading point
    # in proportion to intensity (stochastic: unbiased for the VPLs; integrator lightcuts).
    representatives: Literal["fixed", "stochastic"] = "fixed"
    # Passes averaged, each with its own lights, trees and eye-ray samples (seeds from ``seed``).
    passes: Annotated[int, Field(ge=1, le=MAX_PASSES)] = 1

    @field_validator("continuation_rays")
    @classmethod
    def _continuations_per_pixel(cls, v, info):
        spp = info.data.get("spp")
        if spp is not None and v * spp > MAX_SPP:
            raise ValueError(f"{v} x render.spp {spp} = {v * spp:,} continuations per pixel, more than "
                             f"{MAX_SPP:,} (lightcuts.limits.MAX_SPP)")
        return v


class RunConfig(Strict):
    """name : the output folder's name under renders/, a plain folder name (no path);
    seed : 0 <= seed <= MAX_SEED (the kernels take it as an int64)."""

    name: str = "render"
    seed: Annotated[int, Field(ge=0, le=MAX_SEED)] = 0
    scene: SceneConfig
    camera: CameraConfig = CameraConfig()
    lights: LightsConfig = LightsConfig()
    tree: TreeConfig = TreeConfig()
    render: RenderConfig = RenderConfig()
    # Set by load_config: the folder relative paths are resolved against.
    base_dir: str = Field(default=".", exclude=True)

    @field_validator("name")
    @classmethod
    def _plain_name(cls, v):
        if v in ("", ".", "..") or "/" in v or "\\" in v or "\0" in v or v != v.strip():
            raise ValueError(f"{v!r} is not a plain folder name (no path separators, not '.' or '..', "
                             "not empty, no surrounding spaces)")
        return v

    def resolve(self, p: str) -> Path:
        """A config path made absolute against the config file's folder."""
        q = Path(p).expanduser()
        return q if q.is_absolute() else (Path(self.base_dir) / q)


def _models_in(annotation) -> list:
    """The pydantic model classes an annotation holds (through Optional, list, dict, Annotated)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in get_args(annotation) for m in _models_in(arg)]


def _field_at(parts: list[str]):
    """(the model class holding the dotted key ``parts``, its FieldInfo or None) in RunConfig."""
    model, keyed = RunConfig, False
    for p in parts[:-1]:
        if p.isdigit() or keyed:  # a list's index, or a dict's key (scene.materials.<name>)
            keyed = False
            continue
        info = model.model_fields.get(p)
        inner = _models_in(info.annotation) if info is not None else []
        if not inner:
            return None, None
        model = inner[0]
        keyed = "dict" in str(info.annotation)
    return model, model.model_fields.get(parts[-1]) if parts else None


#: Examples of a value's form, by the length a list field must have.
_LIST_EXAMPLES = {2: "[640, 480]", 3: "[0.5, 0.5, 0.5]", 4: "[0, 0, 64, 64]"}


def _min_lengths(info_or_type) -> list[int]:
    """The ``min_length`` bounds found in a field (its metadata, and Annotated types in its annotation)."""
    found = [m.min_length for m in getattr(info_or_type, "metadata", []) if hasattr(m, "min_length")]
    annotation = getattr(info_or_type, "annotation", None) if hasattr(info_or_type, "metadata") else info_or_type
    for arg in get_args(annotation):
        found += _min_lengths(arg)
    return found


def _expected_form(info) -> str:
    """`` (expected <form>, e.g. <example>)`` for a list field, from its length bounds; else ''."""
    n = next(iter(_min_lengths(info)), None) if info is not None else None
    if n is None:
        return ""
    return f" (expected a list of {n} numbers, e.g. {_LIST_EXAMPLES.get(n, '[1, 2]')})"


def _format_error(source: str, exc: ValidationError, keys=()) -> str:
    """One line for the first error; an unknown key that an override made (``keys``: the dotted keys
    set, which make their sections on the way, each a text or (key, the option that set it or None))
    is named in full, as the override gave it, and the error names the option (``--set``) rather
    than the file. An unknown key suggests the nearest known one of its section; a list of the
    wrong type gives the expected form and an example."""
    e = exc.errors()[0]
    parts = [str(p) for p in e["loc"] if not (isinstance(p, str) and p.startswith("function-"))]
    loc = ".".join(parts)
    msg = e["msg"]
    given = [(k, "--set") if isinstance(k, str) else k for k in keys]  # (dotted key, what set it)
    given = [(k.strip(), label) for k, label in given]
    if e["type"] == "extra_forbidden":
        msg = "unknown key"
        model, _ = _field_at(parts)
        if model is not None:
            near = difflib.get_close_matches(parts[-1], list(model.model_fields), n=1, cutoff=0.6)
            msg += f" (did you mean {'.'.join(parts[:-1] + near[:1])}?)" if near else \
                f" (known: {', '.join(k for k in model.model_fields if k != 'base_dir')})"
        loc = next((k for k, _ in given if k.split(".")[:len(parts)] == parts), loc)
    elif e["type"] == "value_error":
        msg = msg.removeprefix("Value error, ")
    elif e["type"] == "list_type":
        msg += _expected_form(_field_at(parts)[1])
    more = f" (and {len(exc.errors()) - 1} more)" if len(exc.errors()) > 1 else ""
    setter = next((label for k, label in given
                   if label and (loc == k or loc.startswith(k + ".") or k.startswith(loc + "."))), None)
    if setter is not None:  # --set gave it, not the file (the API's values keep the file's name)
        return f"{setter} {loc}: {msg}{more}"
    return f"{source}: {loc or '<top>'}: {msg}{more}"


def _apply_override(data: dict, assignment: str, source: str) -> None:
    if "=" not in assignment:
        raise LightcutsError(f"--set {assignment!r}: expected key=value")
    key, _, text = assignment.partition("=")
    parts = key.strip().split(".")
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        what = " ".join(str(getattr(exc, "problem", None) or exc).split())
        raise LightcutsError(f"--set {assignment!r}: value is not valid YAML ({what}); quote it to give a string")
    if not key.strip() or any(not p for p in parts):
        raise LightcutsError(f"--set {assignment!r}: expected a dotted key, e.g. render.eps=0.01")
    set_key(data, key, value, "--set ")


def set_key(data: dict, key: str, value, prefix: str = "") -> None:
    """Set the dotted ``key`` (e.g. ``render.eps``) of a raw config dict to ``value``, making the
    sections on the way; a number after a list names its entry (``scene.meshes.0.file``).
    LightcutsError ``<prefix><key>: <section> is not a section`` (or the index is out of range)."""
    parts = key.strip().split(".")
    node = data
    for i, p in enumerate(parts):
        last = i == len(parts) - 1
        if isinstance(node, list):
            if not p.isdigit() or int(p) >= len(node):
                raise LightcutsError(f"{prefix}{key}: {'.'.join(parts[:i])} has {len(node)} entries, "
                                     f"{p!r} is not one of their indices")
            p = int(p)
        elif not isinstance(node, dict):
            raise LightcutsError(f"{prefix}{key}: {parts[i - 1]} is not a section")
        elif not last and node.get(p) is None:
            node[p] = {}
        if last:
            node[p] = value
        else:
            node = node[p]


def check_files(cfg: RunConfig, source: str) -> None:
    """Every file the config names exists and is readable: checked before any work starts."""
    named = [(f"scene.meshes.{i}.file", m.file) for i, m in enumerate(cfg.scene.meshes)]
    if cfg.scene.mitsuba is not None:
        named.append(("scene.mitsuba", cfg.scene.mitsuba))
    if cfg.lights.environment is not None and cfg.lights.environment.file is not None:
        named.append(("lights.environment.file", cfg.lights.environment.file))
    for key, p in named:
        path = cfg.resolve(p)
        if not path.is_file():
            raise LightcutsError(f"{source}: {key}: no such file {str(path)!r}")


def config_from_dict(data: dict, source: str = "<config>", base_dir: str | Path = ".", keys=()) -> RunConfig:
    """Validate a config dict; LightcutsError with one line on any problem. ``keys``: the dotted keys
    that overrides set, named in full when unknown."""
    if not isinstance(data, dict):
        raise LightcutsError(f"{source}: expected a mapping at the top level")
    try:
        cfg = RunConfig.model_validate({**data, "base_dir": str(base_dir)})
    except ValidationError as exc:
        raise LightcutsError(_format_error(source, exc, keys)) from None
    sc = cfg.scene
    if sc.builtin is None and sc.procedural is None and sc.mitsuba is None and not sc.meshes and not sc.emitters:
        raise LightcutsError(f"{source}: scene: needs builtin, procedural, mitsuba, meshes or emitters")
    if (sc.builtin is not None) + (sc.procedural is not None) + (sc.mitsuba is not None) > 1:
        raise LightcutsError(f"{source}: scene: give at most one of builtin, procedural or mitsuba")
    env = cfg.lights.environment
    if env is not None and env.file is not None and env.procedural is not None:
        raise LightcutsError(f"{source}: lights.environment: give one of file or procedural, not both")
    if env is not None and env.file is None and env.procedural is None and sc.mitsuba is None:
        raise LightcutsError(f"{source}: lights.environment: give file or procedural (neither: the environment "
                             "of a scene.mitsuba file)")
    check_files(cfg, source)
    return cfg


def load_config(path: str | Path, overrides: list[str] = (), values: dict | None = None) -> RunConfig:
    """Read, override (``key.sub=value``, value parsed as YAML; then ``values``, dotted key -> Python
    value, as the Python API gives them) and validate a run config."""
    from lightcuts.io import as_path

    path = as_path(path, "config")
    if not isinstance(overrides, (list, tuple)) or not all(isinstance(a, str) for a in overrides):
        raise LightcutsError(f"overrides {overrides!r}: expected a list of 'key=value' texts")
    if values is not None and not isinstance(values, dict):
        raise LightcutsError(f"values {values!r}: expected a dict of dotted keys and values")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise LightcutsError(f"{path}: cannot read config ({exc.strerror or exc})") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise LightcutsError(f"{path}: not a UTF-8 text file (byte {exc.start})") from None
    try:
        data = yaml.safe_load(text)
    except RecursionError:
        raise LightcutsError(f"{path}: invalid YAML (nested too deeply)") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" line {mark.line + 1}:" if mark is not None else ""
        what = " ".join(str(getattr(exc, "problem", None) or exc).split())
        raise LightcutsError(f"{path}:{where} invalid YAML ({what})") from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise LightcutsError(f"{path}: expected a mapping at the top level")
    for a in overrides:
        _apply_override(data, a, str(path))
    for key, value in (values or {}).items():
        if not isinstance(key, str) or not key.strip() or any(not p for p in key.strip().split(".")):
            raise LightcutsError(f"{key!r}: expected a dotted key, e.g. render.eps")
        set_key(data, key, value)
    keys = [(a.partition("=")[0], "--set") for a in overrides] + [(k, None) for k in values or {}]
    return config_from_dict(data, str(path), path.parent.resolve(), keys)
