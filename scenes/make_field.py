"""Writes scenes/field.toml: one torus (scenes/torus.obj) placed 81 times as [[instance]]s
of a named [[mesh]], in a 9 x 9 grid, each turned and coloured by its place.
Run from the repository: python3 scenes/make_field.py"""

HEAD = """# A field of instances, written by scenes/make_field.py: one torus mesh (scenes/torus.obj)
# named "torus" and placed again 80 times with [[instance]]; the triangles are shared.
[camera]
position = [0, 9, 14]
look_at = [0, 0, 0]
fov = 40
width = 800
height = 500

[settings]
background = [0.55, 0.7, 0.9]

[[light]]
position = [-8, 14, 10]

[[light]]
kind = "directional"
direction = [1, -2, -0.5]
color = [0.4, 0.4, 0.35]

[material.ground]
color = [0.45, 0.5, 0.35]
specular = 0

[material.copper]
color = [0.9, 0.45, 0.2]
shininess = 40

[material.teal]
color = [0.15, 0.6, 0.6]
shininess = 40

[material.chrome]
color = [0.8, 0.8, 0.85]
reflectivity = 0.6
shininess = 80

[[quad]]
corner = [-20, 0, 20]
edge_u = [40, 0, 0]
edge_v = [0, 0, -40]
material = "ground"
"""

materials = ["copper", "teal", "chrome"]
out = [HEAD]
for k in range(81):
    i, j = k % 9 - 4, k // 9 - 4
    x, z = 2.2 * i, 2.2 * j
    turn = (37 * k) % 360
    tilt = 30 + (k * 17) % 50
    t = f"{{ rotate = [{tilt}, {turn}, 0], translate = [{x:.1f}, 0.9, {z:.1f}], scale = 0.6 }}"
    m = materials[(i + j) % 3]
    if k == 0:
        out.append(f'[[mesh]]\nname = "torus"\nfile = "torus.obj"\nmaterial = "{m}"\ntransform = {t}\n')
    else:
        out.append(f'[[instance]]\nof = "torus"\nmaterial = "{m}"\ntransform = {t}\n')
with open("scenes/field.toml", "w") as f:
    f.write("\n".join(out))
