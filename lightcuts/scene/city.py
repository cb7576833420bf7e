"""A city at night: a 400 m street grid of lit windows, street lamps and strings of bulbs, with
``emitters`` emitting triangles (10^3 to 4 x 10^6), most of them hidden from any one point.

Layout (metres, y up, streets on every side): ``NB`` x ``NB`` blocks of ``BLOCK`` m on a pitch of
``PITCH`` m, so x, z in [0, EXTENT] = [0, 400]; a street is ``STREET`` m from building line to
building line, a 10 m road between 3 m sidewalks (each block stands on a 0.15 m plinth that reaches
over its sidewalks), on a ground box ``MARGIN`` m wider than the city. A block is split into 1 to 3
by 1 to 3 lots; each lot's building is flush with the street and 2 m from its neighbours (alleys),
4 to 48 storeys of ``STOREY`` m, taller towards the centre; a tall one may stand as a set-back tower
on a podium, and some carry a plant room on the roof.

Emitters (one-sided, ``emitters`` E triangles in all, hit to within one window's panes):

- street lamps (``LAMP_SHARE`` of E): on the sidewalks, two per side of every block edge; a pole, an
  arm over the road and a housing whose underside is the lamp head, an LED array of tiles facing
  down (normal -y), sodium orange or white per street. Fewer lamps than slots at small E (the
  camera's street first), more tiles per head at large E.
- strings of bulbs (``BULB_SHARE``): across the inner streets every 6 m along a block, sagging 1 m
  from 6.5 m high on a thin wire; each bulb an octahedron of 8 triangles facing away from its
  centre. Whole blocks of a street get strings, the camera's street first.
- windows (the rest): a slot every 3 m along every facade at every storey above the ground floor,
  1.6 x 1.8 m, 2 cm off the wall. A seeded subset of at most ``MAX_LIT`` of the slots is lit (busy
  buildings and whole floors together), each window split into panes (more panes at large E), warm,
  neutral, cool or television blue, its radiance lognormal over a 16x range (its power kept whatever
  its panes); the rest are dark glossy glass.

The camera stands at eye height in the middle north-south street near its southern end, looking
north down the street: the nearest emitters are metres away, the farthest 400 m. Non-emitting
geometry stays below 100,000 triangles (most of it the unlit windows).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from lightcuts.scene.batches import boxes, octahedra, quads, tiles
from lightcuts.scene.registry import SCENES, SEED, emitters as emitters_param
from lightcuts.scene.scene import Camera, Scene
from lightcuts.scene.shapes import PartList, material as _m

NB, BLOCK, STREET, SIDEWALK = 6, 48.0, 16.0, 3.0
PITCH = BLOCK + STREET
EXTENT = NB * PITCH + STREET
MARGIN, KERB = 20.0, 0.15
STOREY, ALLEY = 3.4, 2.0
WINDOW_W, WINDOW_H, SILL, WINDOW_PITCH, WINDOW_OFF = 1.6, 1.8, 0.9, 3.0, 0.02
MAX_LIT = 0.5
LAMP_SHARE, BULB_SHARE = 0.15, 0.15
LAMP_FRACTIONS = (0.25, 0.75)  # where along a block edge the lamps stand
POLE_H, ARM, HEAD = 7.5, 1.8, (0.6, 0.3)  # head: across, along the street
STRING_Y, SAG, STRING_SPACING, BULB_R, BULBS_PER_STRING, WIRE_SEGMENTS = 6.5, 1.0, 6.0, 0.04, 30, 16
RESOLUTION = (192, 128)


#: Surface name -> material (``scene.materials`` overrides any field by name); an emitter's radiance
#: is the material's emission times its own factor (windows: lognormal around 1).
PALETTE = {
    "road": _m((0.08, 0.08, 0.085), (0.08, 0.08, 0.08), 40),
    "sidewalk": _m((0.30, 0.29, 0.27)),
    "concrete": _m((0.45, 0.44, 0.42)),
    "brick": _m((0.38, 0.20, 0.13)),
    "stone": _m((0.55, 0.50, 0.42)),
    "cladding": _m((0.10, 0.11, 0.12), (0.20, 0.20, 0.20), 200),
    "roof": _m((0.22, 0.22, 0.22)),
    "glass": _m((0.02, 0.02, 0.025), (0.25, 0.25, 0.25), 400),
    "metal": _m((0.15, 0.15, 0.16), (0.20, 0.20, 0.20), 60),
    "wire": _m((0.05, 0.05, 0.05)),
    "window_warm": _m((0.8, 0.8, 0.8), emission=(6.0, 3.7, 1.8)),
    "window_neutral": _m((0.8, 0.8, 0.8), emission=(6.0, 5.1, 4.1)),
    "window_cool": _m((0.8, 0.8, 0.8), emission=(5.0, 5.5, 6.0)),
    "window_tv": _m((0.8, 0.8, 0.8), emission=(1.4, 1.9, 3.2)),
    "lamp_sodium": _m((0.8, 0.8, 0.8), emission=(400.0, 180.0, 40.0)),
    "lamp_white": _m((0.8, 0.8, 0.8), emission=(300.0, 300.0, 280.0)),
    "bulb": _m((0.8, 0.8, 0.8), emission=(120.0, 80.0, 35.0)),
}
FACADES = ("concrete", "brick", "stone", "cladding")
WINDOW_COLOURS = ("window_warm", "window_neutral", "window_cool", "window_tv")
#: Colour probabilities of a lit window in a residential and an office building.
COLOUR_P = {"residential": (0.70, 0.15, 0.05, 0.10), "office": (0.10, 0.40, 0.50, 0.0)}


def _lots(rng: np.random.Generator, x0: float, z0: float) -> list[tuple[float, float, float, float]]:
    """The building footprints (x0, z0, x1, z1) of the block at (x0, z0): 1 to 3 lots a side,
    flush with the streets, ALLEY apart."""
    out = []
    cuts = []
    for _ in range(2):
        n = int(rng.choice([1, 2, 3], p=[0.2, 0.5, 0.3]))
        w = rng.uniform(0.7, 1.3, n)
        cuts.append(np.concatenate([[0.0], np.cumsum(w) / w.sum()]) * BLOCK)
    for a0, a1 in zip(cuts[0][:-1], cuts[0][1:]):
        for b0, b1 in zip(cuts[1][:-1], cuts[1][1:]):
            out.append((x0 + a0 + (ALLEY / 2 if a0 > 0 else 0), z0 + b0 + (ALLEY / 2 if b0 > 0 else 0),
                        x0 + a1 - (ALLEY / 2 if a1 < BLOCK else 0), z0 + b1 - (ALLEY / 2 if b1 < BLOCK else 0)))
    return out


class Buildings(NamedTuple):
    """The building masses (a building is one box, or a podium and a set-back tower on it).

    lo, hi : (M, 3) float64, the masses' boxes
    s0, s1 : (M,) int64, the storeys with windows on the mass, [s0, s1)
    owner : (M,) int64, the building of each mass
    facade : (B,) int64, each building's facade material (index into FACADES)
    office : (B,) bool, office (cool light, whole floors lit) rather than residential
    plant : (P, 2, 3) float64, plant rooms on the roofs (lo, hi), without windows
    """

    lo: np.ndarray
    hi: np.ndarray
    s0: np.ndarray
    s1: np.ndarray
    owner: np.ndarray
    facade: np.ndarray
    office: np.ndarray
    plant: np.ndarray


def buildings(rng: np.random.Generator) -> Buildings:
    """Every block's buildings (module docstring): lots from ``_lots``, storeys lognormal around a
    mean that falls off from the centre, towers on podiums and plant rooms at random."""
    lo, hi, s0, s1, owner, plant = [], [], [], [], [], []
    centre, b = 0.5 * EXTENT, -1
    for i in range(NB):
        for j in range(NB):
            for fx0, fz0, fx1, fz1 in _lots(rng, STREET + i * PITCH, STREET + j * PITCH):
                b += 1
                d = math.hypot(0.5 * (fx0 + fx1) - centre, 0.5 * (fz0 + fz1) - centre)
                mean = 4.0 + 26.0 * math.exp(-(d / 130.0) ** 2)
                storeys = int(np.clip(round(mean * rng.lognormal(0.0, 0.35)), 4, 48))
                top = KERB + storeys * STOREY + 0.6
                inset = rng.uniform(3.0, 5.0)
                if storeys >= 12 and rng.random() < 0.6 and min(fx1 - fx0, fz1 - fz0) > 2 * inset + 8:
                    podium = int(rng.integers(2, 5))
                    # the podium's top 0.6 m parapet hides the tower's foot
                    lo += [(fx0, KERB, fz0), (fx0 + inset, KERB + podium * STOREY, fz0 + inset)]
                    hi += [(fx1, KERB + podium * STOREY + 0.6, fz1), (fx1 - inset, top, fz1 - inset)]
                    s0 += [1, podium]
                    s1 += [podium, storeys]
                    owner += [b, b]
                else:
                    lo.append((fx0, KERB, fz0))
                    hi.append((fx1, top, fz1))
                    s0.append(1)
                    s1.append(storeys)
                    owner.append(b)
                if rng.random() < 0.5:
                    (rx0, _, rz0), (rx1, ry, rz1) = lo[-1], hi[-1]
                    cx, cz = rx0 + rng.uniform(0.3, 0.7) * (rx1 - rx0), rz0 + rng.uniform(0.3, 0.7) * (rz1 - rz0)
                    half = 0.15 * min(rx1 - rx0, rz1 - rz0)
                    plant.append(((cx - half, ry - 0.1, cz - half), (cx + half, ry + rng.uniform(2.5, 4.5), cz + half)))
    return Buildings(np.array(lo, np.float64), np.array(hi, np.float64), np.array(s0, np.int64),
                     np.array(s1, np.int64), np.array(owner, np.int64), rng.integers(len(FACADES), size=b + 1),
                     rng.random(b + 1) < 0.4, np.array(plant, np.float64).reshape(-1, 2, 3))


def window_slots(lo: np.ndarray, hi: np.ndarray, s0: np.ndarray, s1: np.ndarray):
    """Every window slot of the masses' four facades: corner (S, 3) (2 cm off the wall), u (S, 3)
    along the facade (WINDOW_W long), outward normal (S, 3), mass id (S,), storey (S,). The window
    is ``corner + [0, 1] u + [0, WINDOW_H] y``, its normal ``u x y`` the facade's outward one."""
    # faces: outward normal n, the horizontal direction t = y x n (so t x y = n) and the face's extent
    normals = np.array([[1, 0, 0], [-1, 0, 0], [0, 0, 1], [0, 0, -1]], np.float64)
    t = np.cross([0.0, 1.0, 0.0], normals)
    m = len(lo)
    mass = np.repeat(np.arange(m), 4)
    n = np.tile(normals, (m, 1))
    tt = np.tile(t, (m, 1))
    centre = 0.5 * (lo + hi)[mass] + 0.5 * n * (hi - lo)[mass]
    width = np.abs(tt * (hi - lo)[mass]).sum(axis=1)
    start = centre - 0.5 * width[:, None] * tt  # the face's end the t axis starts from
    ncol = np.maximum(0, np.floor((width - 2.0) / WINDOW_PITCH)).astype(np.int64)
    nst = np.maximum(0, s1 - s0)[mass]
    count = ncol * nst
    face = np.repeat(np.arange(len(count)), count)
    local = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    col, storey = local % ncol[face], s0[mass[face]] + local // ncol[face]
    along = 0.5 * (width - ncol * WINDOW_PITCH)[face] + (col + 0.5) * WINDOW_PITCH - 0.5 * WINDOW_W
    corner = start[face] + along[:, None] * tt[face] + WINDOW_OFF * n[face]
    corner[:, 1] = KERB + storey * STOREY + SILL
    return corner, WINDOW_W * tt[face], n[face], mass[face], storey


def _segments():
    """Street segments (a street between two intersections): axis (0: the street runs along z, at
    x = its centre; 1: along x), street index k (0..NB), block index i along it; (G, 3) int64."""
    a, k, i = np.meshgrid([0, 1], np.arange(NB + 1), np.arange(NB), indexing="ij")
    return np.stack([a.ravel(), k.ravel(), i.ravel()], axis=1)


def _street_frame(axis: np.ndarray, k: np.ndarray, along: np.ndarray, across: np.ndarray, y: np.ndarray):
    """World points (N, 3) of street points: ``across`` from the street's centre line, ``along``
    its length, height ``y``."""
    centre = k * PITCH + 0.5 * STREET
    x = np.where(axis == 0, centre + across, along)
    z = np.where(axis == 0, along, centre + across)
    return np.stack([x, y, z], axis=1)


CAMERA_STREET = (0, NB // 2)  # the north-south street through the middle
CAMERA_Z = STREET + (NB - 1) * PITCH + 0.75 * BLOCK


def _priority(segs: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Order of the segments: the camera's street from the camera northwards, then the rest shuffled."""
    own = (segs[:, 0] == CAMERA_STREET[0]) & (segs[:, 1] == CAMERA_STREET[1])
    first = np.flatnonzero(own)[np.argsort(-segs[own, 2], kind="stable")]
    rest = np.flatnonzero(~own)
    return np.concatenate([first, rest[rng.permutation(len(rest))]])


def lamp_slots(rng: np.random.Generator):
    """Lamp positions in priority order (segment by segment, ``_priority``): axis, street (N,),
    pole foot (N, 3) at kerb height, side (N,) (-1 or +1 of the centre line; the arm reaches back
    over the road); only on the sides of a street that have a block."""
    segs = _segments()[_priority(_segments(), rng)]
    side, frac = (a.ravel() for a in np.meshgrid([-1, 1], LAMP_FRACTIONS, indexing="ij"))
    g = np.repeat(segs, len(side), axis=0)
    side, frac = np.tile(side, len(segs)), np.tile(frac, len(segs))
    keep = np.where(side < 0, g[:, 1] >= 1, g[:, 1] <= NB - 1)
    g, side, frac = g[keep], side[keep], frac[keep]
    along = STREET + g[:, 2] * PITCH + frac * BLOCK
    across = side * (0.5 * STREET - SIDEWALK + 0.5)
    return g[:, 0], g[:, 1], _street_frame(g[:, 0], g[:, 1], along, across, np.full(len(g), KERB)), side


def string_slots(rng: np.random.Generator):
    """Bulb string positions in priority order (whole segments of inner streets): axis, street,
    along (N,) each."""
    segs = _segments()
    segs = segs[(segs[:, 1] >= 1) & (segs[:, 1] <= NB - 1)]
    segs = segs[_priority(segs, rng)]
    offsets = np.arange(0.5 * STRING_SPACING, BLOCK, STRING_SPACING)
    own = (segs[:, 0] == CAMERA_STREET[0]) & (segs[:, 1] == CAMERA_STREET[1])
    # along the camera's street strings come northwards from the camera
    offsets_per = np.where(own[:, None], offsets[::-1][None, :], offsets[None, :])
    along = STREET + segs[:, 2:3] * PITCH + offsets_per
    n = len(offsets)
    return np.repeat(segs[:, 0], n), np.repeat(segs[:, 1], n), along.ravel()


def budget(emitters: int, n_windows: int, n_lamps: int, n_strings: int) -> dict:
    """How many of each emitter: lamps (count, tiles across x along), bulbs (strings, bulbs), lit
    windows (count, panes across x up); their triangles total ``emitters`` to within a window's."""
    lamp_quads = max(1, int(LAMP_SHARE * emitters) // 2)
    lamps = min(n_lamps, lamp_quads)
    per = lamp_quads // lamps
    along = max(1, round(math.sqrt(per * HEAD[1] / HEAD[0])))
    across = max(1, per // along)
    bulbs = max(1, int(BULB_SHARE * emitters) // 8)
    strings = min(n_strings, max(1, math.ceil(bulbs / BULBS_PER_STRING)))
    rest = emitters - 2 * lamps * across * along - 8 * bulbs
    panes = max(1, math.ceil(rest / (2 * MAX_LIT * n_windows)))
    up = max(1, round(math.sqrt(panes * WINDOW_H / WINDOW_W)))
    side = math.ceil(panes / up)
    lit = max(1, round(rest / (2 * side * up)))
    return dict(lamps=lamps, lamp_tiles=(across, along), strings=strings, bulbs=bulbs, windows=lit,
                panes=(side, up))


def _lit_windows(rng, mass, storey, owner, lit: int) -> np.ndarray:
    """Sorted ids of ``lit`` of the slots, drawn without replacement in proportion to a weight per
    building (lognormal) times one per floor of a building (gamma, many dark floors): Efraimidis and
    Spirakis' keys ``log(u) / w``, the largest taken."""
    b = owner[mass]
    activity = rng.lognormal(0.0, 1.0, owner.max() + 1)
    floors = rng.gamma(0.5, 1.0, (owner.max() + 1, storey.max() + 1))
    w = activity[b] * floors[b, storey] + 1e-3
    keys = np.log(rng.random(len(w))) / w
    return np.sort(np.argpartition(-keys, lit - 1)[:lit])


class City(NamedTuple):
    """The generated city: its parts, its buildings (the windows lie on the masses' faces) and the
    emitter counts of :func:`budget`."""

    parts: PartList
    buildings: Buildings
    plan: dict


def city_parts(emitters: int, seed: int) -> City:
    """The city (module docstring) with about ``emitters`` emitting triangles, from ``seed``."""
    rng = np.random.default_rng(seed)
    bld = buildings(rng)
    corner, u, _, mass, storey = window_slots(bld.lo, bld.hi, bld.s0, bld.s1)
    lamp_axis, lamp_k, pole, side = lamp_slots(rng)
    str_axis, str_k, str_along = string_slots(rng)
    plan = budget(emitters, len(corner), len(pole), len(str_along))
    parts = PartList()
    parts.add(boxes([-MARGIN, -0.3, -MARGIN], [EXTENT + MARGIN, 0.0, EXTENT + MARGIN]), "road")
    ij = np.stack(np.meshgrid(np.arange(NB), np.arange(NB), indexing="ij"), -1).reshape(-1, 2)
    b0 = STREET + ij * PITCH - SIDEWALK
    parts.add(boxes(np.insert(b0, 1, 0.0, axis=1), np.insert(b0 + BLOCK + 2 * SIDEWALK, 1, KERB, axis=1)), "sidewalk")
    for f, name in enumerate(FACADES):
        pick = bld.facade[bld.owner] == f
        if pick.any():
            parts.add(boxes(bld.lo[pick], bld.hi[pick]), name)
    if len(bld.plant):
        parts.add(boxes(bld.plant[:, 0], bld.plant[:, 1]), "roof")

    # windows: the lit ones in colour groups, the rest glass
    lit = _lit_windows(rng, mass, storey, bld.owner, plan["windows"])
    dark = np.ones(len(corner), bool)
    dark[lit] = False
    up = np.array([0.0, WINDOW_H, 0.0])
    parts.add(quads(corner[dark], u[dark], up), "glass", closed=False)
    kind = np.where(bld.office[bld.owner[mass[lit]]], 1, 0)
    cum = np.cumsum([COLOUR_P["residential"], COLOUR_P["office"]], axis=1)
    colour = np.minimum((rng.random(len(lit))[:, None] > cum[kind]).sum(axis=1), len(WINDOW_COLOURS) - 1)
    across, high = plan["panes"]
    gap = min(0.02, 0.1 * WINDOW_W / across, 0.1 * WINDOW_H / high)
    pane_area = (WINDOW_W / across - 2 * gap) * (WINDOW_H / high - 2 * gap) * across * high
    radiance = np.clip(rng.lognormal(0.0, 0.5, len(lit)), 0.25, 4.0) * (WINDOW_W * WINDOW_H / pane_area)
    for c, name in enumerate(WINDOW_COLOURS):
        pick = lit[colour == c]
        if len(pick):
            parts.add(tiles(corner[pick], u[pick], up, across, high, gap), name, closed=False,
                      scale=np.repeat(radiance[colour == c], 2 * across * high))
    _lamps(parts, rng, plan, lamp_axis, lamp_k, pole, side)
    _strings(parts, plan, str_axis, str_k, str_along)
    return City(parts, bld, plan)


def _lamps(parts: PartList, rng, plan: dict, axis, k, pole, side) -> None:
    """The first ``plan["lamps"]`` lamp slots: pole, arm, housing and the downward LED head."""
    n = plan["lamps"]
    axis, k, pole, side = axis[:n], k[:n], pole[:n], side[:n]
    across_dir = np.where(axis[:, None] == 0, [1.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    along_dir = np.where(axis[:, None] == 0, [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    reach = -side[:, None] * across_dir  # from the pole over the road
    y = np.array([0.0, 1.0, 0.0])
    lo, hi = [], []
    for centre, half, y0, y1 in ((pole, 0.08 * (across_dir + along_dir), KERB, POLE_H),
                                 (pole + 0.5 * ARM * reach, 0.5 * ARM * across_dir + 0.05 * along_dir,
                                  POLE_H - 0.1, POLE_H),
                                 (pole + 0.85 * ARM * reach, (0.5 * HEAD[0] + 0.05) * across_dir
                                  + (0.5 * HEAD[1] + 0.05) * along_dir, POLE_H - 0.25, POLE_H - 0.1)):
            c = centre.copy()
            c[:, 1] = 0.0
            lo.append(c - half + y0 * y)
            hi.append(c + half + y1 * y)
    parts.add(boxes(np.concatenate(lo), np.concatenate(hi)), "metal")
    head = pole + 0.85 * ARM * reach
    head[:, 1] = POLE_H - 0.252
    across, along = plan["lamp_tiles"]
    gap = min(0.004, 0.1 * HEAD[0] / across, 0.1 * HEAD[1] / along)
    power = HEAD[0] * HEAD[1] / ((HEAD[0] / across - 2 * gap) * (HEAD[1] / along - 2 * gap) * across * along)
    white = rng.random(NB + 1) < 0.6, rng.random(NB + 1) < 0.6  # per street of each axis
    is_white = np.where(axis == 0, white[0][k], white[1][k])
    for ax in (0, 1):
        # u along x, v along z: normal x cross z = -y (facing down)
        size = (HEAD[0], HEAD[1]) if ax == 0 else (HEAD[1], HEAD[0])
        nu, nv = (across, along) if ax == 0 else (along, across)
        for name, colour in (("lamp_white", True), ("lamp_sodium", False)):
            pick = (axis == ax) & (is_white == colour)
            if pick.any():
                corner = head[pick] - [0.5 * size[0], 0.0, 0.5 * size[1]]
                parts.add(tiles(corner, [size[0], 0, 0], [0, 0, size[1]], nu, nv, gap), name, closed=False,
                          scale=power)


def _strings(parts: PartList, plan: dict, axis, k, along) -> None:
    """The first ``plan["strings"]`` string slots, ``plan["bulbs"]`` bulbs shared out among them;
    each on a wire (a 2 cm ribbon) sagging between the building lines."""
    n, bulbs = plan["strings"], plan["bulbs"]
    axis, k, along = axis[:n], k[:n], along[:n]
    per = np.full(n, bulbs // n) + (np.arange(n) < bulbs % n)

    def sag(t):
        return STRING_Y - SAG * 4.0 * t * (1.0 - t)

    s = np.repeat(np.arange(n), per)
    t = (np.arange(bulbs) - np.repeat(np.cumsum(per) - per, per) + 0.5) / per[s]
    centre = _street_frame(axis[s], k[s], along[s], (t - 0.5) * STREET, sag(t) - 0.08)
    parts.add(octahedra(centre, BULB_R), "bulb", closed=False)
    tw = np.linspace(0.0, 1.0, WIRE_SEGMENTS + 1)
    ws = np.repeat(np.arange(n), WIRE_SEGMENTS)
    t0, t1 = np.tile(tw[:-1], n), np.tile(tw[1:], n)
    p0 = _street_frame(axis[ws], k[ws], along[ws], (t0 - 0.5) * STREET, sag(t0))
    p1 = _street_frame(axis[ws], k[ws], along[ws], (t1 - 0.5) * STREET, sag(t1))
    width = np.where(axis[ws][:, None] == 0, [0.0, 0.0, 0.02], [0.02, 0.0, 0.0])
    parts.add(quads(p0 - 0.5 * width, p1 - p0, width), "wire", closed=False)


def camera() -> Camera:
    """At eye height in the middle north-south street near its southern end, looking north."""
    x = CAMERA_STREET[1] * PITCH + 0.5 * STREET
    return Camera((x - 2.0, 1.7, CAMERA_Z), (x + 1.0, 9.0, 0.0), (0, 1, 0), 45.0, *RESOLUTION)


@SCENES.register("city", params={"emitters": emitters_param(100_000), "seed": SEED}, resolution=RESOLUTION,
                 description="a 400 m street grid at night: lit windows, street lamps, strings of bulbs")
def city_scene(params: dict, materials=None, exhibits=(), offsets=(), name: str = "city") -> Scene:
    """The city (module docstring) with its camera; ``materials``: overrides by ``PALETTE`` name."""
    return city_parts(params["emitters"], params["seed"]).parts.to_scene(PALETTE, materials, camera(), name)
