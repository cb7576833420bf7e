r"""The rows of the efficiency study (``lightcuts study``): what each row renders, read from the
command line (``--row TEXT``) or a rows file (``--rows FILE.yaml``), resolved and checked before any
work.

A row is a set of config overrides on the study's config: an integrator (any ``render.integrator``
value) and its own ``--set``-style overrides, crossed with light-tree builders where the integrator
uses trees; or a reference renderer's path tracer (``tracer:NAME``, an entry of
:data:`lightcuts.integrators.references.REFERENCES`, e.g. Mitsuba 3's). Because a row is overrides,
an integrator or a parameter registered later is a row as soon as it exists; the plan step checks it
as it checks a render.

The command-line form (also an entry of a rows file):

    SPEC [KEY=VALUE ...]

``SPEC`` is ``NAME`` or ``NAME:PARAM=VALUE[,PARAM=VALUE...]`` (``render.integrator: {type: NAME,
PARAM: VALUE}``, values read as YAML) or ``tracer:NAME``. A dotted ``KEY`` is a config override of
that row (``render.eps=0.05``); a plain one a row option:

* ``label=TEXT``: the row's name in tables and file names (default its SPEC and overrides, e.g.
  ``path:max_depth=8 render.eps=0.05``; ``config`` for a file's row that names no integrator; a row
  that uses light trees gets ``/BUILDER`` appended);
* ``builders=A,B``: the builders crossed with this row (default ``--builders``, else the config's);
  only for an integrator that uses light trees;
* ``ladder=passes|spp``: what the ladder of sample counts counts: passes (each with its own lights,
  trees and eye rays; the running mean is the image, as ``render.passes``) or samples per pixel (one
  render per count at ``render.spp``, one pass). Default: passes for integrators that use light
  trees (their lights are redrawn only by a new pass), spp otherwise; path tracer rows count spp.
  Either way the ladder takes the place of ``render.passes``;
* ``samples=1,4,16``: the ladder's counts (default 1, 2, 4, ... until the time budget);
* ``converging=false``: keep the config's ``render.compensation`` and ``render.representatives``
  (by default an integrator with the ``converging`` trait runs with both on: compensation and
  stochastic representatives, the unbiased settings).

A rows file is YAML: a list (or ``rows:`` holding one) whose entries are such texts or mappings with
the keys ``integrator`` (a ``render.integrator`` value; default the config's) or ``tracer``, ``set``
(a list of ``KEY=VALUE`` or a mapping of dotted keys), and the options above.
"""

from __future__ import annotations

import json
import shlex
from dataclasses import dataclass, field

from lightcuts.errors import LightcutsError

#: A row's plain options.
OPTIONS = ("label", "builders", "ladder", "samples", "converging")
LADDERS = ("passes", "spp")
#: The config sections every row shares with the study's config (one scene, one reference).
SHARED = (("scene", lambda c: c.scene), ("camera", lambda c: c.camera), ("render.crop", lambda c: c.render.crop),
          ("lights.sun", lambda c: c.lights.sun), ("lights.environment", lambda c: c.lights.environment))
#: What the converging settings set (before the row's own overrides, which win).
CONVERGING = ("render.compensation=true", "render.representatives=stochastic")


@dataclass
class StudyRow:
    """One resolved row.

    label : its name; source : the row as given (for messages); group : the rows that differ only by
    their builder share it; cfg : its RunConfig (the study's for a path tracer row); plan : its
    Plan (None for a path tracer row); tracer : the REFERENCES name of a path tracer row, else None;
    builder : the builder's name where the integrator uses light trees, else None; uses_trees : it
    makes lights and trees; ladder : ``passes`` or ``spp``; samples : the ladder's counts given, or
    None (1, 2, 4, ... up to ``max_samples``); overrides : the row's overrides after the command's.
    """

    label: str
    source: str
    group: str
    cfg: object
    plan: object = None
    tracer: str | None = None
    builder: str | None = None
    uses_trees: bool = False
    ladder: str = "spp"
    samples: list | None = None
    max_samples: int = 1
    overrides: list = field(default_factory=list)

    def record(self) -> dict:
        """The row for report.json: label, group, tracer, builder, ladder, overrides, plugins."""
        return {"label": self.label, "group": self.group, "source": self.source, "tracer": self.tracer,
                "builder": self.builder, "ladder": self.ladder, "overrides": self.overrides,
                "plugins": self.plan.record() if self.plan is not None else None}


def parse_row(text, where: str) -> dict:
    """The mapping form of a row's text ``SPEC [KEY=VALUE ...]`` (module docstring); LightcutsError
    naming ``where`` (e.g. ``--row 'path'``)."""
    import yaml

    if not isinstance(text, str):
        raise LightcutsError(f"{where}: expected a text 'SPEC [KEY=VALUE ...]' or a mapping")
    try:
        tokens = shlex.split(text)
    except ValueError as exc:
        raise LightcutsError(f"{where}: {exc}") from None
    if not tokens or "=" in tokens[0].partition(":")[0]:
        raise LightcutsError(f"{where}: starts with no integrator; expected 'NAME[:PARAM=VALUE,...]' or "
                             "'tracer:NAME', then KEY=VALUE overrides or options")
    head, rest = tokens[0], tokens[1:]
    name, _, params = head.partition(":")
    row = {}
    if name == "tracer":
        row["tracer"] = params
    elif params:
        spec = {"type": name}
        for item in params.split(","):
            key, eq, value = item.partition("=")
            if not eq or not key.strip():
                raise LightcutsError(f"{where}: integrator parameter {item!r}: expected PARAM=VALUE")
            try:
                spec[key.strip()] = yaml.safe_load(value)
            except yaml.YAMLError:
                raise LightcutsError(f"{where}: render.integrator.{key.strip()}: {value!r} is not a YAML value") from None
        row["integrator"] = spec
    else:
        row["integrator"] = name
    for token in rest:
        key, eq, value = token.partition("=")
        if not eq or not key:
            raise LightcutsError(f"{where}: {token!r}: expected KEY=VALUE (a dotted config key or one of "
                                 f"{', '.join(OPTIONS)})")
        if "." in key:
            row.setdefault("set", []).append(token)
        elif key in OPTIONS:
            row[key] = value
        else:
            raise LightcutsError(f"{where}: {key!r} is not a row option ({', '.join(OPTIONS)}) nor a dotted config key")
    return row


def read_rows(path) -> list[tuple[str, dict]]:
    """The rows of a rows file: [(how messages name it, mapping)]; LightcutsError naming the file."""
    import yaml

    from lightcuts.io import as_path

    p = as_path(path, "--rows")
    try:
        data = yaml.safe_load(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise LightcutsError(f"--rows {path}: cannot read ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise LightcutsError(f"--rows {path}: not a UTF-8 text file (byte {exc.start})") from None
    except yaml.YAMLError as exc:
        what = " ".join(str(getattr(exc, "problem", None) or exc).split())
        raise LightcutsError(f"--rows {path}: invalid YAML ({what})") from None
    if isinstance(data, dict) and set(data) == {"rows"}:
        data = data["rows"]
    if not isinstance(data, list) or not data:
        raise LightcutsError(f"--rows {path}: expected a list of rows (or 'rows:' holding one)")
    out = []
    for i, item in enumerate(data, 1):
        where = f"--rows {path}: row {i}"
        if isinstance(item, str):
            out.append((where, parse_row(item, where)))
        elif isinstance(item, dict):
            unknown = sorted(set(item) - {"integrator", "tracer", "set", *OPTIONS}, key=str)
            if unknown:
                raise LightcutsError(f"{where}: {unknown[0]!r} is not a row key (integrator, tracer, set, "
                                     f"{', '.join(OPTIONS)})")
            out.append((where, dict(item)))
        else:
            raise LightcutsError(f"{where}: expected a text 'SPEC [KEY=VALUE ...]' or a mapping")
    return out


def _overrides(row: dict, where: str) -> list[str]:
    """The row's ``set`` as ``KEY=VALUE`` texts."""
    given = row.get("set") or []
    if isinstance(given, dict):
        return [f"{k}={json.dumps(v)}" for k, v in given.items()]
    if not isinstance(given, list) or not all(isinstance(s, str) for s in given):
        raise LightcutsError(f"{where}: set: expected a list of KEY=VALUE texts or a mapping of dotted keys")
    return list(given)


def _counts(value, where: str, hi: int) -> list[int] | None:
    """``samples``: increasing positive integers up to ``hi``, at most MAX_POINTS of them."""
    from lightcuts.limits import MAX_POINTS

    if value is None:
        return None
    items = value.split(",") if isinstance(value, str) else value if isinstance(value, list) else [value]
    try:
        counts = [int(str(v).strip()) for v in items]
    except ValueError:
        raise LightcutsError(f"{where}: samples {value!r}: expected sample counts, e.g. 1,4,16") from None
    if not counts or any(b <= a for a, b in zip(counts, counts[1:])) or counts[0] < 1 or counts[-1] > hi:
        raise LightcutsError(f"{where}: samples {value!r}: expected increasing counts from 1 to {hi:,}")
    if len(counts) > MAX_POINTS:
        raise LightcutsError(f"{where}: samples: {len(counts)} counts, more than {MAX_POINTS} "
                             "(lightcuts.limits.MAX_POINTS)")
    return counts


def _flag(value, where: str, key: str) -> bool:
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.lower() in ("true", "false"):
        return value.lower() == "true"
    raise LightcutsError(f"{where}: {key} {value!r}: expected true or false")


def max_samples(cfg, ladder: str) -> int:
    """The largest count of the ladder ``ladder`` that the config's limits allow: MAX_PASSES passes
    or MAX_SPP samples per pixel (x continuation_rays with compensation), and the eye rays of the
    render (lightcuts.pipeline.plan.check_work: one pass of ``render.spp`` per pass of a ``passes``
    ladder, one pass per point of a ``spp`` ladder) at most MAX_EYE_RAYS."""
    from lightcuts.limits import MAX_EYE_RAYS, MAX_PASSES, MAX_SPP
    from lightcuts.pipeline.plan import check_work

    r = cfg.render
    per = check_work(cfg, None) // r.passes // (1 if ladder == "passes" else r.spp)  # rays per count
    hi = MAX_PASSES if ladder == "passes" else MAX_SPP // (r.continuation_rays if r.compensation else 1)
    return max(1, min(hi, MAX_EYE_RAYS // max(per, 1)))


def resolve_rows(config, overrides, given: list[tuple[str, dict]], builders=None) -> list[StudyRow]:
    """The study's rows, every one loaded and planned (LightcutsError naming the row and the key at
    fault, before any work). config : the config file; overrides : the command's ``--set``; given :
    [(how messages name the row, its mapping)] (:func:`parse_row`, :func:`read_rows`); builders :
    ``--builders`` (comma-separated names or a list), crossed with the rows that use light trees and
    name none."""
    from lightcuts.config import load_config
    from lightcuts.pipeline.comparing import names

    from lightcuts.trees.registry import BUILDERS

    base = load_config(config, list(overrides))
    default_builders = names(builders, "--builders") if builders is not None else None
    for b in default_builders or ():
        try:
            BUILDERS.entry(b)
        except LightcutsError as exc:
            raise LightcutsError(f"--builders: {exc}") from None
    rows = []
    for where, row in given:
        try:
            rows += _resolve(config, list(overrides), base, row, where, default_builders, load_config, names)
        except LightcutsError as exc:
            message = str(exc)
            raise LightcutsError(message if message.startswith(where) else f"{where}: {message}") from None
    seen = set()
    for r in rows:
        if r.label in seen:
            raise LightcutsError(f"row {r.label!r}: two rows have this label; give one of them label=NAME")
        seen.add(r.label)
    return rows


def _resolve(config, overrides, base, row, where, default_builders, load_config, names) -> list[StudyRow]:
    from lightcuts.integrators.registry import INTEGRATORS
    from lightcuts.integrators.references import make_reference
    from lightcuts.pipeline.plan import plan_run, uses_trees
    from lightcuts.trees.spec import config_tree, tree_spec

    if "integrator" in row and "tracer" in row:
        raise LightcutsError("give integrator or tracer, not both")
    label = str(row.get("label") or _default_label(row))
    ladder = row.get("ladder")
    if ladder is not None and ladder not in LADDERS:
        raise LightcutsError(f"ladder {ladder!r}: expected {' or '.join(LADDERS)}")
    sets = _overrides(row, where)
    if "tracer" in row:
        for key in ("set", "builders", "converging"):
            if row.get(key) is not None:
                raise LightcutsError(f"{key}: a path tracer row renders the study's config as it is")
        if ladder == "passes":
            raise LightcutsError("ladder passes: a path tracer row counts samples per pixel (ladder spp)")
        try:
            tracer = make_reference(str(row["tracer"]))
            try:
                tracer.check(base, "path")
            finally:
                tracer.close()
        except LightcutsError as exc:  # the renderers' messages name --renderer; a row names tracer:
            raise LightcutsError(str(exc).replace("--renderer: ", "tracer: ").replace("--renderer ", "tracer:")) from None
        hi = max_samples(base, "spp")
        return [StudyRow(label, where, label, base, tracer=tracer.name, ladder="spp",
                         samples=_counts(row.get("samples"), where, hi), max_samples=hi)]
    spec = row.get("integrator", base.render.integrator)
    extra = [f"render.integrator={json.dumps(spec)}"]
    cfg = load_config(config, overrides + sets + extra)
    integrator = INTEGRATORS.resolve(cfg.render.integrator, "render.integrator")
    if _flag(row.get("converging", True), where, "converging") and integrator.trait("converging", False):
        cfg = load_config(config, overrides + list(CONVERGING) + sets + extra)
    for key, part in SHARED:
        if part(cfg) != part(base):
            raise LightcutsError(f"{key}: the rows share the study's scene, camera and reference; set it with "
                                 "--set for all rows")
    trees = uses_trees(cfg, integrator)
    ladder = ladder or ("passes" if trees else "spp")
    hi = max_samples(cfg, ladder)
    samples = _counts(row.get("samples"), where, hi)
    mine = row.get("builders")
    if not trees:
        if mine is not None:
            raise LightcutsError(f"builders: integrator {integrator.name!r} uses no light trees (a path tracer "
                                 "row has none to cross)")
        plan = plan_run(cfg, render=True)
        return [StudyRow(label, where, label, cfg, plan, ladder=ladder, samples=samples, max_samples=hi,
                         overrides=sets + extra)]
    chosen = names(mine, "builders") if mine is not None else default_builders
    if chosen is None:
        plan = plan_run(cfg, render=True)
        return [StudyRow(f"{label}/{plan.tree.name}", where, label, cfg, plan, builder=plan.tree.name, uses_trees=True,
                         ladder=ladder, samples=samples, max_samples=hi, overrides=sets + extra)]
    _, metric, c, keys = config_tree(cfg.tree)
    out = []
    for b in chosen:
        spec_b = tree_spec(b, metric, c, {**keys, "builder": "builders"}, drop_unread=True)
        plan = plan_run(cfg, render=True, tree=spec_b)
        out.append(StudyRow(f"{label}/{b}", where, label, cfg, plan, builder=b, uses_trees=True, ladder=ladder,
                            samples=samples, max_samples=hi, overrides=sets + extra + [f"tree.builder={b}"]))
    return out


def _default_label(row: dict) -> str:
    """A mapping row's name: its integrator (``NAME`` or ``NAME:PARAM=VALUE,...``) or ``tracer:NAME``,
    then its overrides."""
    if "tracer" in row:
        return f"tracer:{row['tracer']}"
    spec = row.get("integrator", "config")
    if isinstance(spec, dict):
        params = ",".join(f"{k}={v}" for k, v in spec.items() if k != "type")
        spec = f"{spec.get('type')}" + (f":{params}" if params else "")
    sets = row.get("set") or []
    sets = [f"{k}={v}" for k, v in sets.items()] if isinstance(sets, dict) else list(sets)
    return " ".join([str(spec), *map(str, sets)])
