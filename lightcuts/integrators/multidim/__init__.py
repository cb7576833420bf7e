"""Multidimensional lightcuts (Walter, Arbree, Bala, Greenberg 2006): per pixel, gather points over
the pixel and the lens, a gather tree over them, and one cut through the product of the gather tree
and the light trees."""

from lightcuts.integrators.multidim.render import (render_multidimensional,  # noqa: F401
                                              render_multidimensional_reference)
