"""Lights and materials built in Python: point, directional and spot lights, distance
attenuation, Fresnel and absorbing glass. Each renders exactly as the same scene read
from TOML, is checked as the TOML reader checks it, and survives pickling."""

import math
import pickle

import numpy as np
import pytest

import whitted
from conftest import ROOT

CAMERA = (0, 3, 7), (0, 0.5, 0)

HEAD = """
[camera]
position = [0, 3, 7]
look_at = [0, 0.5, 0]
fov = 45
width = 64
height = 48
[settings]
background = [0.05, 0.05, 0.1]
[material.floor]
color = [0.8, 0.8, 0.8]
specular = 0
[material.red]
color = [1, 0.2, 0.1]
shininess = 80
[[quad]]
corner = [-5, 0, 5]
edge_u = [10, 0, 0]
edge_v = [0, 0, -10]
material = "floor"
[[sphere]]
center = [0.5, 0.8, 0]
radius = 0.8
material = "red"
"""


def base_scene():
    """The scene of HEAD, without lights, built in code."""
    scene = whitted.Scene(whitted.Camera(*CAMERA, fov=45, width=64, height=48), background=(0.05, 0.05, 0.1))
    scene.add(whitted.Quad((-5, 0, 5), (10, 0, 0), (0, 0, -10)), whitted.Material(color=(0.8, 0.8, 0.8), specular=0))
    scene.add(whitted.Sphere((0.5, 0.8, 0), 0.8), whitted.Material(color=(1, 0.2, 0.1), shininess=80))
    return scene


# Each light as Python builds it and as a scene file writes it.
LIGHTS = {
    "point": (
        whitted.PointLight((-2, 4, 3)),
        "position = [-2, 4, 3]\n",
    ),
    "point with attenuation": (
        whitted.PointLight((-2, 4, 3), color=(1, 0.9, 0.7), intensity=3, attenuation=(1, 0.2, 0.1)),
        "kind = \"point\"\nposition = [-2, 4, 3]\ncolor = [1, 0.9, 0.7]\nintensity = 3\n"
        "attenuation = [1, 0.2, 0.1]\n",
    ),
    "directional": (
        whitted.DirectionalLight((-1, -0.6, -0.8), color=(1, 0.85, 0.6), intensity=0.7),
        "kind = \"directional\"\ndirection = [-1, -0.6, -0.8]\ncolor = [1, 0.85, 0.6]\nintensity = 0.7\n",
    ),
    "unit directional": (
        whitted.DirectionalLight((0, -1, 0)),
        "kind = \"directional\"\ndirection = [0, -1, 0]\n",
    ),
    "spot": (
        whitted.SpotLight((0.5, 5, 1), (0, -1, -0.2), inner_angle=12, outer_angle=20),
        "kind = \"spot\"\nposition = [0.5, 5, 1]\ndirection = [0, -1, -0.2]\ninner_angle = 12\nouter_angle = 20\n",
    ),
    "spot with everything": (
        whitted.SpotLight((0.5, 5, 1), (0, -2, 0), 15, 15, color=(0.3, 0.6, 1), intensity=2.5,
                          attenuation=(0, 0, 0.04)),
        "kind = \"spot\"\nposition = [0.5, 5, 1]\ndirection = [0, -2, 0]\ninner_angle = 15\nouter_angle = 15\n"
        "color = [0.3, 0.6, 1]\nintensity = 2.5\nattenuation = [0, 0, 0.04]\n",
    ),
}


def toml_with(*names):
    return HEAD + "".join(f"[[light]]\n{LIGHTS[n][1]}" for n in names)


def code_with(*names):
    scene = base_scene()
    for n in names:
        scene.add(LIGHTS[n][0])
    return scene


@pytest.mark.parametrize("name", list(LIGHTS))
def test_each_light_renders_as_the_same_light_read_from_toml(name):
    ours = whitted.render(code_with(name))
    theirs = whitted.render(whitted.Scene.from_toml(toml_with(name)))
    assert np.array_equal(ours, theirs)
    assert ours.max() > 0.2, "the light lights something"


def test_all_kinds_together_render_as_the_toml_scene_and_each_one_counts():
    names = list(LIGHTS)
    ours = whitted.render(code_with(*names))
    assert np.array_equal(ours, whitted.render(whitted.Scene.from_toml(toml_with(*names))))
    for i in range(len(names)):
        fewer = whitted.render(code_with(*(names[:i] + names[i + 1:])))
        assert not np.array_equal(fewer, ours), f"{names[i]} made no difference"


def test_lights_added_with_add_light_and_to_a_toml_scene():
    via_add_light = base_scene()
    via_add_light.add_light(LIGHTS["spot"][0])
    assert np.array_equal(whitted.render(via_add_light), whitted.render(code_with("spot")))
    # Lights added in code to a scene read from TOML join its own.
    scene = whitted.Scene.from_toml(toml_with("point"))
    scene.add(LIGHTS["directional"][0]).add(LIGHTS["spot"][0])
    assert "3 lights" in repr(scene)
    assert np.array_equal(whitted.render(scene),
                          whitted.render(whitted.Scene.from_toml(toml_with("point", "directional", "spot"))))


def top_down(light, ambient=0.0, size=64):
    """A grey floor (y = 0), seen straight from above (10 units up, 60° field of view,
    so the image spans 2·10·tan 30° = 11.5 units), lit by `light` alone."""
    cam = whitted.Camera((0, 10, 0), (0, 0, 0), up=(0, 0, -1), fov=60, width=size, height=size)
    scene = whitted.Scene(cam, ambient=ambient)
    scene.add(whitted.Quad((-20, 0, 20), (40, 0, 0), (0, 0, -40)), whitted.Material(color=(0.8, 0.8, 0.8), specular=0))
    scene.add(light)
    return whitted.render(scene)


def test_a_spot_lights_inside_its_cone_and_nothing_outside():
    # 4 units above the floor, 10° inner and 15° outer: full light within 0.71 units of
    # the point below, none past 1.07 (about 6 pixels).
    image = top_down(whitted.SpotLight((0, 4, 0), (0, -1, 0), 10, 15))
    px = 64 / (2 * 10 * math.tan(math.radians(30)))  # pixels per unit on the floor
    centre = image[32, 32]
    assert centre.min() > 0.5
    inside = image[32, 32 + int(0.4 * px)]
    assert inside.min() > 0.5
    for r in (1.3, 2.0, 5.0):
        assert image[32, 32 + int(r * px)].max() == 0.0, r
        assert image[32 - int(r * px), 32].max() == 0.0, r
    assert image[1, 1].max() == 0.0
    lit = (image.max(axis=2) > 0).sum()
    # About π·(1.07·5.56)² = 111 pixels; none far outside the outer cone.
    assert 60 < lit < 200, lit
    # The same light as a point light lights the whole floor.
    point = top_down(whitted.PointLight((0, 4, 0)))
    assert point[1, 1].min() > 0 and (point.max(axis=2) > 0).all()
    # A wider cone lights more.
    wide = top_down(whitted.SpotLight((0, 4, 0), (0, -1, 0), 30, 40))
    assert (wide.max(axis=2) > 0).sum() > 4 * lit


def test_attenuation_darkens_with_distance():
    position = (0, 2, 0)
    plain = top_down(whitted.PointLight(position))
    none = top_down(whitted.PointLight(position, attenuation=(1, 0, 0)))
    assert np.array_equal(plain, none), "(1, 0, 0) is no attenuation"
    faded = top_down(whitted.PointLight(position, attenuation=(1, 0.5, 0.25)))
    assert (faded <= plain).all() and faded.max() > 0
    # The share left falls with distance from the point below the light, across the
    # whole row, and is about 1 / (1 + 0.5·d + 0.25·d²) at distance d.
    ratio = faded[32, 32:, 1] / plain[32, 32:, 1]
    assert (np.diff(ratio) <= 1e-6).all()
    assert ratio[-1] < 0.5 * ratio[0]
    px = 64 / (2 * 10 * math.tan(math.radians(30)))
    for col in (32, 40, 50, 63):
        x = (col + 0.5 - 32) / px
        d = math.hypot(x, 2.0)
        assert ratio[col - 32] == pytest.approx(1 / (1 + 0.5 * d + 0.25 * d * d), rel=0.03), col
    # A spot light's attenuation multiplies its cone.
    spot = top_down(whitted.SpotLight(position, (0, -1, 0), 40, 50))
    spot_faded = top_down(whitted.SpotLight(position, (0, -1, 0), 40, 50, attenuation=(0, 0, 1)))
    assert (spot_faded <= spot).all() and spot_faded[32, 32].max() > 0
    assert np.array_equal(spot_faded > 0, spot > 0)


GLASS_TOML = """
[camera]
position = [0, 1.5, 6]
look_at = [0, 0.8, 0]
fov = 40
width = 64
height = 48
[settings]
background = [0.55, 0.7, 0.9]
[[light]]
position = [-4, 8, 6]
[material.checker]
texture = { kind = "checker", size = 1, colors = [[0.9, 0.9, 0.9], [0.2, 0.2, 0.25]] }
specular = 0
[material.glass]
color = [1, 1, 1]
shininess = 200
reflectivity = 0.05
transparency = 0.9
ior = 1.5
fresnel = true
absorption = [0.6, 0.05, 0.5]
[[quad]]
corner = [-6, 0, 6]
edge_u = [12, 0, 0]
edge_v = [0, 0, -12]
material = "checker"
[[sphere]]
center = [0, 1, 0]
radius = 1
material = "glass"
"""


def glass_scene(**glass):
    scene = whitted.Scene(whitted.Camera((0, 1.5, 6), (0, 0.8, 0), fov=40, width=64, height=48),
                          background=(0.55, 0.7, 0.9))
    scene.add(whitted.PointLight((-4, 8, 6)))
    checker = whitted.Checker(1, colors=((0.9, 0.9, 0.9), (0.2, 0.2, 0.25)))
    scene.add(whitted.Quad((-6, 0, 6), (12, 0, 0), (0, 0, -12)), whitted.Material(texture=checker, specular=0))
    kw = dict(color=(1, 1, 1), shininess=200, reflectivity=0.05, transparency=0.9, ior=1.5)
    kw.update(glass)
    scene.add(whitted.Sphere((0, 1, 0), 1), whitted.Material(**kw))
    return scene


def test_fresnel_and_absorbing_glass_renders_as_the_toml_material():
    glass = dict(fresnel=True, absorption=(0.6, 0.05, 0.5))
    ours = whitted.render(glass_scene(**glass))
    assert np.array_equal(ours, whitted.render(whitted.Scene.from_toml(GLASS_TOML)))
    # Each of the two is passed on: without it the picture changes.
    assert not np.array_equal(ours, whitted.render(glass_scene(absorption=(0.6, 0.05, 0.5))))
    assert not np.array_equal(ours, whitted.render(glass_scene(fresnel=True)))
    # The defaults are the plain material's.
    assert np.array_equal(whitted.render(glass_scene()),
                          whitted.render(glass_scene(fresnel=False, absorption=(0, 0, 0))))
    m = whitted.Material()
    assert (m.fresnel, m.absorption) == (False, (0.0, 0.0, 0.0))
    # Absorbing red and blue more than green: through the sphere, green wins.
    centre = ours[22:28, 29:35].reshape(-1, 3).mean(axis=0)
    assert centre[1] > centre[0] and centre[1] > centre[2], centre


SPOT = dict(position=(0, 5, 0), direction=(0, -1, 0), inner_angle=10, outer_angle=20)

# Bad values, each given to Python and written into a scene file: both refuse it and
# name the field. (kind, fields changed from a good light of that kind, field named)
BAD_VALUES = [
    ("point", dict(attenuation=(0, 0, 0)), "attenuation"),
    ("point", dict(attenuation=(1, -1, 0)), "attenuation"),
    ("point", dict(attenuation=(1, math.inf, 0)), "attenuation"),
    ("point", dict(intensity=-1), "intensity"),
    ("point", dict(color=(1, -0.5, 0)), "color"),
    ("point", dict(position=(0, math.nan, 0)), "position"),
    ("directional", dict(direction=(0, 0, 0)), "direction"),
    ("directional", dict(direction=(0, -1, math.inf)), "direction"),
    ("directional", dict(intensity=math.nan), "intensity"),
    ("spot", dict(inner_angle=0), "inner_angle"),
    ("spot", dict(inner_angle=-5), "inner_angle"),
    ("spot", dict(outer_angle=90), "outer_angle"),
    ("spot", dict(outer_angle=89.999999999), "outer_angle"),  # 90 in float32
    ("spot", dict(inner_angle=30, outer_angle=20), "inner_angle"),
    ("spot", dict(inner_angle=math.nan), "inner_angle"),
    ("spot", dict(direction=(0, 0, 0)), "direction"),
    ("spot", dict(attenuation=(0, 0, 0)), "attenuation"),
    ("spot", dict(attenuation=(0, 0, -1)), "attenuation"),
]

GOOD = {
    "point": dict(position=(0, 5, 0)),
    "directional": dict(direction=(0, -1, 0)),
    "spot": SPOT,
}
CLASSES = {"point": whitted.PointLight, "directional": whitted.DirectionalLight, "spot": whitted.SpotLight}


def toml_value(v):
    if isinstance(v, tuple):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, float) and not math.isfinite(v):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
    return repr(v)


CAMERA_TOML = "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov = 40\n"


def light_toml(kind, fields):
    body = "".join(f"{k} = {toml_value(v)}\n" for k, v in fields.items())
    return f"{CAMERA_TOML}[[light]]\nkind = \"{kind}\"\n{body}"


@pytest.mark.parametrize("kind,change,field", BAD_VALUES)
def test_bad_light_values_are_refused_as_the_toml_reader_refuses_them(kind, change, field):
    fields = {**GOOD[kind], **change}
    with pytest.raises(ValueError, match=f"^light.{field}: "):
        CLASSES[kind](**fields)
    with pytest.raises(whitted.SceneError, match=f": {field}: "):
        whitted.Scene.from_toml(light_toml(kind, fields))


@pytest.mark.parametrize("kind,change", [
    ("point", dict(attenuation=(1, 0, 0))),
    ("point", dict(attenuation=(0, 0, 1), intensity=0)),
    ("spot", dict(inner_angle=20, outer_angle=20)),
    ("spot", dict(inner_angle=0.001, outer_angle=89.99)),
    ("directional", dict(direction=(1e-3, 0, 0))),
])
def test_edge_values_both_accept(kind, change):
    fields = {**GOOD[kind], **change}
    CLASSES[kind](**fields)
    whitted.Scene.from_toml(light_toml(kind, fields))


def test_bad_arguments_raise_type_and_value_errors_naming_the_field():
    for make, exc, field in [
        (lambda: whitted.PointLight((0, 0, 0), attenuation="1 0 0"), TypeError, "attenuation"),
        (lambda: whitted.PointLight((0, 0, 0), attenuation=(1, 0)), ValueError, "attenuation"),
        (lambda: whitted.PointLight((0, 0, 0), attenuation=1), TypeError, "attenuation"),
        (lambda: whitted.PointLight((0, 0, 0), intensity="2"), TypeError, "intensity"),
        (lambda: whitted.PointLight((0, 0, 0), intensity=True), TypeError, "intensity"),
        (lambda: whitted.DirectionalLight(None), TypeError, "direction"),
        (lambda: whitted.DirectionalLight((0, -1, 0), color=(1, 1)), ValueError, "color"),
        (lambda: whitted.SpotLight((0, 5, 0), (0, -1, 0), "10", 20), TypeError, "inner_angle"),
        (lambda: whitted.SpotLight((0, 5, 0), (0, -1, 0), 10, None), TypeError, "outer_angle"),
        (lambda: whitted.SpotLight((0, 5, 0), "down", 10, 20), TypeError, "direction"),
        (lambda: whitted.Material(fresnel=1), TypeError, "fresnel"),
        (lambda: whitted.Material(fresnel="yes"), TypeError, "fresnel"),
        (lambda: whitted.Material(absorption=(1, 0, 0)), ValueError, "absorption"),
        (lambda: whitted.Material(transparency=0.5, absorption=(1, -1, 0)), ValueError, "absorption"),
        (lambda: whitted.Material(transparency=0.5, absorption=(1, math.inf, 0)), ValueError, "absorption"),
        (lambda: whitted.Material(transparency=0.5, absorption=(1, 0)), ValueError, "absorption"),
        (lambda: whitted.Material(transparency=0.5, absorption="red"), TypeError, "absorption"),
    ]:
        with pytest.raises(exc, match=field):
            make()
    # Fields of another kind are not taken, as in scene files.
    with pytest.raises(TypeError):
        whitted.DirectionalLight((0, -1, 0), attenuation=(1, 0, 0))
    with pytest.raises(TypeError):
        whitted.DirectionalLight((0, -1, 0), position=(0, 0, 0))
    with pytest.raises(TypeError):
        whitted.PointLight((0, 0, 0), direction=(0, -1, 0))
    with pytest.raises(TypeError):
        whitted.SpotLight((0, 5, 0), (0, -1, 0))  # the angles are required
    scene = base_scene()
    with pytest.raises(TypeError, match="no material"):
        scene.add(whitted.SpotLight(**SPOT), whitted.Material())
    with pytest.raises(TypeError):
        scene.add_light(whitted.Sphere((0, 0, 0), 1))
    # The material checks as the TOML reader does: no absorption without transparency,
    # none is fine without it.
    whitted.Material(absorption=(0, 0, 0), fresnel=True)
    for bad in ("absorption = [1, 0, 0]\n", "transparency = 0.5\nabsorption = [1, -1, 0]\n", "fresnel = 1\n"):
        with pytest.raises(whitted.SceneError):
            whitted.Scene.from_toml(f"{CAMERA_TOML}[material.g]\n{bad}")
    # Nothing went wrong in the scene along the way.
    assert whitted.render(scene).shape == (48, 64, 3)


def test_pickling_keeps_every_light_and_material():
    names = list(LIGHTS)
    built = code_with(*names)
    built.add(whitted.Sphere((-1.5, 1, 0), 0.7), whitted.Material(transparency=0.9, ior=1.5, fresnel=True,
                                                                  absorption=(0.5, 0, 0.5)))
    read = whitted.Scene.from_toml(toml_with(*names))
    # A scene read from TOML, then changed (settings, a light added in code): its base
    # is rebuilt from the text plus the additions, which must keep the file's lights.
    changed = whitted.Scene.from_toml(toml_with(*names))
    changed.background = (0.2, 0.1, 0.1)
    changed.add(whitted.SpotLight((-1, 3, 2), (0, -1, 0), 20, 30, color=(0, 1, 0), attenuation=(1, 0, 0.1)))
    for scene in [built, read, changed]:
        back = pickle.loads(pickle.dumps(scene))
        assert back._base._core is None  # rebuilt from the recipe, not shipped
        assert np.array_equal(whitted.render(back), whitted.render(scene))
        assert repr(back) == repr(scene)
    assert "7 lights" in repr(changed)
    # The changed scene is the file's lights and the added one, not just the added one.
    expected = toml_with(*names).replace("background = [0.05, 0.05, 0.1]", "background = [0.2, 0.1, 0.1]")
    expected += ("[[light]]\nkind = \"spot\"\nposition = [-1, 3, 2]\ndirection = [0, -1, 0]\ninner_angle = 20\n"
                 "outer_angle = 30\ncolor = [0, 1, 0]\nattenuation = [1, 0, 0.1]\n")
    assert np.array_equal(whitted.render(changed), whitted.render(whitted.Scene.from_toml(expected)))
    # The lights themselves pickle as what they are.
    for light, _ in LIGHTS.values():
        assert pickle.loads(pickle.dumps(light)) == light


@pytest.mark.parametrize("name", ["lights.toml", "fresnel.toml"])
def test_the_example_scenes_load_change_and_pickle(name):
    scene = whitted.load(ROOT / "scenes" / name, width=64, height=48)
    image = whitted.render(scene)
    assert image.mean() > 0.05
    scene.ambient = scene.ambient  # rebuilds the base from its text: same picture
    assert np.array_equal(whitted.render(scene), image)
    assert np.array_equal(whitted.render(pickle.loads(pickle.dumps(scene))), image)
