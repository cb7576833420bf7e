"""Limits fixed by the kernels' data layout, and bounds on what sizes a run's work and memory, kept free
of kernels so the config schema can read them.

SLOT_BITS : low bits of a lightcut heap entry that hold its slot (lightcuts.integrators.heap)
MAX_CUT : the largest cut, since the cut's scratch holds max_cut + 2 slots
MAX_COORD : the largest magnitude of a position, a config number or ``tree.c``, and MAX_INTENSITY
    of a light's intensity (per channel): with |x| <= 1e30 a box's squared diagonal L^2 and c^2 stay
    below 1.3e61, so the largest metric, I (L^2 + c^2 S^2)^2 summed over up to 1e10 lights of at most
    1e100, stays below 1e233, far from float64's 1.8e308 (an infinite cost would leave a builder
    with no pair to merge); float32 copies of positions (the kd-tree's nodes) stay finite too
MAX_SEED : the largest seed, since the kernels take it as an int64
MAX_PIXELS : the largest image (and environment map), width x height: 2**25 pixels, 33.5 million
    (e.g. 8192 x 4096); the render's buffers take about 60 bytes a pixel
MAX_EXPOSURE : the largest |render.exposure| in stops, so that 2**exposure is a normal float64
MAX_PASSES : the most ``render.passes`` (each pass makes its lights and trees again)
MAX_CONTINUATION_RAYS : the most ``render.continuation_rays`` (compensation continuations per eye ray)
MAX_TEXELS : the largest texture, width x height texels: 2**26, 67.1 million (e.g. 8192 x 8192);
    textures are kept as float32 linear RGB, 12 bytes a texel, so 768 MiB
MAX_SCENE_TEXELS : the most texels of all the textures a scene reads together: 2**27 (1.5 GiB)
MAX_RADIANCE : the largest emitted radiance of a triangle, per channel, W/(m^2 sr): MAX_COORD, the
    bound of every config number (so of ``emission`` and ``radiance`` there), for files too
MAX_EMITTED_POWER : the largest sum over a scene's emitting triangles of area x radiance (largest
    channel), W/sr (pi times it is the power). Emitters are sampled by luminance and a channel is
    at most 1 / 0.0722 of it, so a direct light carries at most 14 times that and a particle path
    starts with at most 14 pi times it; a diffuse bounce never raises a path's weight and a glossy
    one at most doubles it: the 1e10 left below MAX_INTENSITY is that headroom
MAX_SPP : the most ``render.spp`` (eye rays, or multidimensional gather points, per pixel; also
    ``scaling --gather``) and the most ``render.spp`` x ``render.continuation_rays``: a gather point
    takes up to 1.9 KB of per-thread scratch (31 MB a thread at the limit); 16,384 is 64 times the
    largest gather count of the multidimensional paper
MAX_EYE_RAYS : the most eye rays a run traces, pixels x spp x passes (x continuation_rays with
    compensation): 2**36, 6.9e10, days of work on one core; a 512 x 512 image may still take
    spp x passes up to 262,144
MAX_LIGHTS : the most lights a config asks for (each count, and direct + indirect + environment in
    all; a light file's lights): the light set, its tree, the forest and a builder's scratch take
    about 0.9 KB a light (every builder, at 10^6 lights), 3.6 GB at the limit (the papers' scenes
    have 10^5 to 10^6)
MAX_BOUNCES : the most ``lights.indirect.max_bounces`` and ``reference --max-depth``: the particle
    tracer keeps a VPL slot per bounce of every path in flight; 0.99**1024 < 4e-5 of a path's power
    is left after that many bounces on white walls
MAX_EMITTER_TRIANGLES : the most triangles ``scene.emitters`` adds (grid cells x triangles per
    emitter), as many as the largest procedural scene: about 300 B a triangle with its BVH
MAX_REFERENCE_SPP : the most samples per pixel of a path tracer (``reference --spp``,
    ``compare --mitsuba-spp``): 2**20, a day on one core for a 512 x 512 image; Mitsuba's sampler
    counts in 32 bits
MAX_REPEATS : the most timed runs per point (``scaling --repeats``, ``accel --repeats``): a median of
    more is no steadier
MAX_POINTS : the most entries of a list of study points (``scaling --sizes``, ``--gather``)
"""

SLOT_BITS = 20
MAX_CUT = (1 << SLOT_BITS) - 2
MAX_COORD = 1e30
MAX_INTENSITY = 1e100
MAX_SEED = 2**63 - 1
MAX_PIXELS = 1 << 25
MAX_EXPOSURE = 1000.0
MAX_PASSES = 4096
MAX_CONTINUATION_RAYS = 64
MAX_TEXELS = 1 << 26
MAX_SCENE_TEXELS = 1 << 27
MAX_RADIANCE = MAX_COORD
MAX_EMITTED_POWER = 1e90
MAX_SPP = 1 << 14
MAX_EYE_RAYS = 1 << 36
MAX_LIGHTS = 4_000_000
MAX_BOUNCES = 1024
MAX_EMITTER_TRIANGLES = 4_000_000
MAX_REFERENCE_SPP = 1 << 20
MAX_REPEATS = 1000
MAX_POINTS = 256
