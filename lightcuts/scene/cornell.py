r"""The Cornell box from Cornell's published measured data, in millimetres.

Geometry and camera: the "Cornell Box Data" page of the Cornell University Program of Computer
Graphics (http://www.graphics.cornell.edu/online/box/data.html), vertex lists copied as published
(they are reproduced verbatim by many public renderers' scene files). The box is not a perfect cube:
the red wall leans (its corners are not coplanar, by 3.2 mm) and the floor is narrower than the ceiling.

Each published quad ``(v0, v1, v2, v3)`` becomes the triangles ``(v0, v1, v2)`` and ``(v0, v2, v3)``.
In the published vertex order every quad's right-hand-rule normal already points into the box's open
space (walls, floor and ceiling towards the inside, block faces away from their block, the light down,
-y), so no quad is reordered; ``tests/test_scene.py`` checks it.

One deliberate change of topology, no change of coordinates: the published ceiling quad lies in the
same plane (y = 548.8) as the light quad, so a ray tracer would see two coplanar surfaces where the
light is (z-fighting in camera rays, and shadow rays to light samples blocked by the ceiling). Here the
ceiling is the published quad with the light's rectangle cut out (8 triangles around it, sharing the
light's published corners), so ceiling + light cover exactly the published ceiling quad.

Materials: RGB stand-ins for the measured spectra, from Morgan McGuire's Computer Graphics Archive
``CornellBox-Original.mtl`` (Guedis Cardenas and Morgan McGuire, Williams College 2011, public
domain; the same values are used by Benedikt Bitterli's ``cornell-box`` scene for Mitsuba/pbrt-v3):
white ``Kd 0.725 0.71 0.68``, red ``Kd 0.63 0.065 0.05``, green ``Kd 0.14 0.45 0.091``; light
``Kd 0.78 0.78 0.78``, ``Ke 17 12 4``. All surfaces purely diffuse (Lambertian, as published).

Units: lengths in millimetres. Radiance does not depend on the length unit (images are the same in
any unit), but powers and intensities derived from areas do: a light's intensity ``L * A`` is in
radiance x mm^2.
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from lightcuts.config.schema import Material
from lightcuts.errors import LightcutsError
from lightcuts.scene.loaders import as_material
from lightcuts.scene.registry import SCENES
from lightcuts.scene.scene import Camera, Scene

WHITE = (0.725, 0.71, 0.68)
RED = (0.63, 0.065, 0.05)
GREEN = (0.14, 0.45, 0.091)
LIGHT_ALBEDO = (0.78, 0.78, 0.78)
LIGHT_RADIANCE = (17.0, 12.0, 4.0)

# Published quads, millimetres, in the published vertex order. "Left" and "right" as published:
# seen from the camera (looking along +z, up +y) the red wall (x ~ 556) is on the left.
LIGHT_QUAD = np.array([[343.0, 548.8, 227.0], [343.0, 548.8, 332.0],
                       [213.0, 548.8, 332.0], [213.0, 548.8, 227.0]])
CEILING_QUAD = np.array([[556.0, 548.8, 0.0], [556.0, 548.8, 559.2],
                         [0.0, 548.8, 559.2], [0.0, 548.8, 0.0]])
QUADS: dict[str, np.ndarray] = {
    "floor": np.array([[[552.8, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 559.2], [549.6, 0.0, 559.2]]]),
    "back_wall": np.array([[[549.6, 0.0, 559.2], [0.0, 0.0, 559.2], [0.0, 548.8, 559.2],
                            [556.0, 548.8, 559.2]]]),
    "right_wall": np.array([[[0.0, 0.0, 559.2], [0.0, 0.0, 0.0], [0.0, 548.8, 0.0], [0.0, 548.8, 559.2]]]),
    "left_wall": np.array([[[552.8, 0.0, 0.0], [549.6, 0.0, 559.2], [556.0, 548.8, 559.2],
                            [556.0, 548.8, 0.0]]]),
    "short_block": np.array([
        [[130.0, 165.0, 65.0], [82.0, 165.0, 225.0], [240.0, 165.0, 272.0], [290.0, 165.0, 114.0]],
        [[290.0, 0.0, 114.0], [290.0, 165.0, 114.0], [240.0, 165.0, 272.0], [240.0, 0.0, 272.0]],
        [[130.0, 0.0, 65.0], [130.0, 165.0, 65.0], [290.0, 165.0, 114.0], [290.0, 0.0, 114.0]],
        [[82.0, 0.0, 225.0], [82.0, 165.0, 225.0], [130.0, 165.0, 65.0], [130.0, 0.0, 65.0]],
        [[240.0, 0.0, 272.0], [240.0, 165.0, 272.0], [82.0, 165.0, 225.0], [82.0, 0.0, 225.0]],
    ]),
    "tall_block": np.array([
        [[423.0, 330.0, 247.0], [265.0, 330.0, 296.0], [314.0, 330.0, 456.0], [472.0, 330.0, 406.0]],
        [[423.0, 0.0, 247.0], [423.0, 330.0, 247.0], [472.0, 330.0, 406.0], [472.0, 0.0, 406.0]],
        [[472.0, 0.0, 406.0], [472.0, 330.0, 406.0], [314.0, 330.0, 456.0], [314.0, 0.0, 456.0]],
        [[314.0, 0.0, 456.0], [314.0, 330.0, 456.0], [265.0, 330.0, 296.0], [265.0, 0.0, 296.0]],
        [[265.0, 0.0, 296.0], [265.0, 330.0, 296.0], [423.0, 330.0, 247.0], [423.0, 0.0, 247.0]],
    ]),
}

# Published camera: position, viewing direction +z, up +y, a 35 mm focal length and a 25 x 25 mm film.
CAMERA_POSITION = (278.0, 273.0, -800.0)
CAMERA_LOOK_AT = (278.0, 273.0, 0.0)
CAMERA_UP = (0.0, 1.0, 0.0)
FOCAL_LENGTH = 0.035  # m
FILM_SIZE = 0.025  # m, square
CAMERA_FOV = math.degrees(2.0 * math.atan(0.5 * FILM_SIZE / FOCAL_LENGTH))  # vertical, about 39.31 deg
RESOLUTION = (512, 512)

#: Surface names in the order their triangles appear in the scene.
SURFACES = ("floor", "ceiling", "back_wall", "left_wall", "right_wall", "short_block", "tall_block", "light")

_DEFAULTS = {
    "floor": Material(albedo=list(WHITE)),
    "ceiling": Material(albedo=list(WHITE)),
    "back_wall": Material(albedo=list(WHITE)),
    "left_wall": Material(albedo=list(RED)),
    "right_wall": Material(albedo=list(GREEN)),
    "short_block": Material(albedo=list(WHITE)),
    "tall_block": Material(albedo=list(WHITE)),
    "light": Material(albedo=list(LIGHT_ALBEDO), emission=list(LIGHT_RADIANCE)),
}


def _quads_to_triangles(quads: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(Q, 4, 3) quads -> vertices (4Q, 3), faces (2Q, 3): (v0, v1, v2), (v0, v2, v3) per quad."""
    q = len(quads)
    base = 4 * np.arange(q)[:, None]
    faces = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]], axis=1).reshape(-1, 3)
    return quads.reshape(-1, 3).copy(), faces


def _ceiling_with_hole() -> tuple[np.ndarray, np.ndarray]:
    """The published ceiling quad minus the light's rectangle: 8 vertices, 8 triangles, normals -y.

    Outer corner i pairs with light corner i (both lists run the same way round, corner i of each
    being the same extreme in x and z), so the band between edge i of each is a trapezoid
    (outer i, outer i+1, light i+1, light i), split along its outer-i/light-(i+1) diagonal.
    """
    vertices = np.concatenate([CEILING_QUAD, LIGHT_QUAD])
    faces = []
    for i in range(4):
        j = (i + 1) % 4
        faces += [[i, j, 4 + j], [i, 4 + j, 4 + i]]
    return vertices, np.array(faces)


def cornell_surfaces() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Geometry of each named surface: name -> (vertices (V, 3) float64 mm, faces (F, 3) int), in
    the order of ``SURFACES``."""
    out = {}
    for name in SURFACES:
        if name == "ceiling":
            out[name] = _ceiling_with_hole()
        elif name == "light":
            out[name] = _quads_to_triangles(LIGHT_QUAD[None])
        else:
            out[name] = _quads_to_triangles(QUADS[name])
    return out


def cornell_camera() -> Camera:
    """The published camera: at (278, 273, -800) mm looking along +z, vertical fov
    2 atan(12.5 / 35) degrees, 512 x 512 pixels."""
    return Camera(CAMERA_POSITION, CAMERA_LOOK_AT, CAMERA_UP, CAMERA_FOV, *RESOLUTION)


def _merge_override(name: str, base: Material, override) -> Material:
    """Fields the override sets replace the built-in's; the others keep the built-in values."""
    given = as_material(override, f"scene.materials.{name}")
    return base.model_copy(update={f: getattr(given, f) for f in given.model_fields_set})


def cornell_box(materials: Mapping[str, Mapping | Material] | None = None) -> Scene:
    """The Cornell box, in millimetres as published, with its camera (see the module docstring).

    Parameters
    ----------
    materials : mapping name -> Material or dict, optional
        Overrides of named surfaces (``SURFACES``: floor, ceiling, back_wall, left_wall, right_wall,
        short_block, tall_block, light). The fields given (albedo, specular, exponent, emission)
        replace the built-in's; fields not given keep it. An unknown name is a LightcutsError naming
        ``scene.materials.<name>``.

    Returns
    -------
    Scene
        38 triangles in the order of ``SURFACES`` (``cornell_face_ranges`` gives each surface's ids);
        the only emitter is the light quad (2 triangles, 130 x 105 mm, radiance (17, 12, 4), one-sided,
        normal -y). Name ``"cornell"``.
    """
    materials = dict(materials or {})
    unknown = sorted(set(materials) - set(SURFACES))
    if unknown:
        raise LightcutsError(f"scene.materials.{unknown[0]}: unknown Cornell box surface; "
                             f"valid: {', '.join(SURFACES)}")
    verts, faces, albedo, specular, exponent, emission = [], [], [], [], [], []
    offset = 0
    for name, (v, f) in cornell_surfaces().items():
        mat = _DEFAULTS[name]
        if name in materials:
            mat = _merge_override(name, mat, materials[name])
        verts.append(v)
        faces.append(f + offset)
        offset += len(v)
        n = len(f)
        albedo.append(np.tile(mat.albedo, (n, 1)))
        specular.append(np.tile(mat.specular, (n, 1)))
        exponent.append(np.full(n, mat.exponent))
        emission.append(np.tile(mat.emission, (n, 1)))
    return Scene(np.concatenate(verts), np.concatenate(faces), np.concatenate(albedo),
                 np.concatenate(specular), np.concatenate(exponent), np.concatenate(emission),
                 camera=cornell_camera(), name="cornell")


def cornell_face_ranges() -> dict[str, range]:
    """Triangle ids of each named surface in ``cornell_box()``'s scene."""
    out, start = {}, 0
    for name, (_, f) in cornell_surfaces().items():
        out[name] = range(start, start + len(f))
        start += len(f)
    return out


@SCENES.register("cornell", builtin=True, resolution=RESOLUTION)
def _cornell(params: dict, materials=None, exhibits=(), offsets=(), name: str = "cornell") -> Scene:
    """The Cornell box from Cornell's published data (``cornell_box``), named ``"cornell"``."""
    return cornell_box(materials)
