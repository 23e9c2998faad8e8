#!/usr/bin/env python3
"""Generate ``lbr4p.urdf`` (KUKA LBR4p on a pedestal) from the numbers of the design notes.

The committed ``lbr4p.urdf`` is the output of this script; edit the numbers here and rerun
``python robots/lbr4p/generate_urdf.py`` to keep them in sync.  Only the standard library
is used, so the script runs anywhere.

The script writes two identical files: ``dqcontrol/robots/lbr4p/lbr4p.urdf``, the package
data that ``dqcontrol.model.lbr4p_urdf_path()`` returns and the wheel ships, and the copy
beside this script for readers of the repository.  It also copies this folder's
``README.md`` into the package folder under a one-comment header.  ``tests/test_packaging.py``
checks that the copies agree.

Kinematics: the thesis's standard-DH chain (eq. 4.2-4.3) rewritten with world-aligned link
frames at the physical joint centres (all DH frames are parallel to the base at q = 0).
Dynamics and limits: the CoppeliaSim LBR4p model / public LWR4+ description.
Geometry (cylinders and spheres only) and joint damping: our own choice.
"""

from __future__ import annotations

import math
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: The package data folder (the copy the library uses) and this folder.
PACKAGE_DIR = HERE.parents[1] / "dqcontrol" / "robots" / "lbr4p"
OUTPUTS = [PACKAGE_DIR / "lbr4p.urdf", HERE / "lbr4p.urdf"]
#: Header of the package's copy of the README, whose relative paths name repository files.
README_NOTE = (
    "<!-- Copy of robots/lbr4p/README.md of the dqcontrol repository, written by\n"
    "     robots/lbr4p/generate_urdf.py there; edit the original, not this copy. -->\n"
)

# --- kinematics ---------------------------------------------------------------------------
DH_BASE_Z = 0.51  # DH frame 0 (joint 1's centre) above base_link
PEDESTAL_TOP = 0.3995  # the arm's own base puts joint 1 0.1105 m above the pedestal top
ARM_BASE_HEIGHT = DH_BASE_Z - PEDESTAL_TOP  # 0.1105

# joint i's origin relative to the previous link frame (all pure z offsets) and its axis
JOINT_Z = [0.0, 0.200, 0.200, 0.200, 0.200, 0.190, 0.0675]
JOINT_AXIS = ["0 0 1", "0 -1 0", "0 0 1", "0 -1 0", "0 0 1", "0 -1 0", "0 0 1"]
FLANGE_Z = 0.0105  # flange (DH frame 7) above joint 7's centre

# --- limits (rad, rad/s, N m) ---------------------------------------------------------------
POS_LIMIT_DEG = [170, 120, 170, 120, 170, 120, 170]
VEL_LIMIT_DEG = [110, 110, 128, 128, 204, 184, 184]
EFFORT = [176, 176, 100, 100, 100, 38, 38]
DAMPING = [0.5, 0.5, 0.5, 0.5, 0.2, 0.2, 0.2]  # N m s/rad, our choice (small, realistic)

# --- dynamics: mass, COM (from the joint centre, link frame), Ixx Iyy Izz Iyz about the COM
MASS = [2.7, 2.7, 2.7, 2.7, 1.7, 1.6, 0.3]
COM = [
    (0.0, -0.0257, 0.1196),
    (0.0, 0.0277, 0.0888),
    (0.0, 0.0277, 0.1196),
    (0.0, -0.0257, 0.0889),
    (0.0, -0.0254, 0.0944),
    (0.0, 0.0088, -0.0058),
    (0.0, -0.0005, 0.0),
]
INERTIA = [  # ixx, iyy, izz, iyz
    (0.01634, 0.01617, 0.00503, +0.00353),
    (0.01634, 0.01617, 0.00503, +0.00353),
    (0.01634, 0.01617, 0.00503, -0.00353),
    (0.01634, 0.01617, 0.00503, -0.00353),
    (0.00982, 0.00909, 0.00371, +0.00309),
    (0.00301, 0.00302, 0.00341, 0.0),
    (0.00010, 0.00010, 0.00016, 0.0),
]

# static links (pedestal, arm base) carry no dynamics: a negligible explicit inertial
STATIC_MASS, STATIC_INERTIA = 1e-6, 1e-9

# --- materials ---------------------------------------------------------------------------
MATERIALS = {
    "kuka_orange": "0.96 0.45 0.05 1",
    "lbr_grey": "0.62 0.62 0.64 1",
    "flange_dark": "0.20 0.20 0.22 1",
    "pedestal_grey": "0.38 0.39 0.42 1",
}

# --- geometry (our choice): per link, a list of primitives in the link frame ---------------
# ("cyl", z0, z1, radius, material, collision?) | ("sph", z, radius, material, collision?)
# Capsules are a cylinder plus end spheres.  Collision shapes of links that are not parent and
# child are kept apart at q = 0 and over each single joint's full range (see README).
R12, R34, R5, R6, R7 = 0.070, 0.065, 0.060, 0.045, 0.035
GEOMETRY = {
    "lbr4p_pedestal": [
        ("cyl", 0.0, PEDESTAL_TOP, 0.12, "pedestal_grey", True),
        ("cyl", PEDESTAL_TOP - 0.015, PEDESTAL_TOP, 0.13, "pedestal_grey", False),
    ],
    # frame of lbr4p_link_0 = DH frame 0 (joint 1's centre); its body hangs below it
    "lbr4p_link_0": [
        ("cyl", -ARM_BASE_HEIGHT, -0.005, 0.085, "kuka_orange", True),
        ("cyl", -ARM_BASE_HEIGHT, -ARM_BASE_HEIGHT + 0.02, 0.09, "lbr_grey", False),
    ],
    "lbr4p_link_1": [
        ("cyl", 0.0, 0.200, R12, "kuka_orange", True),
        ("sph", 0.200, R12, "kuka_orange", True),
        ("cyl", 0.0, 0.018, R12 + 0.002, "lbr_grey", False),
    ],
    "lbr4p_link_2": [
        ("sph", 0.0, R12, "kuka_orange", True),
        ("cyl", 0.0, 0.200, R12, "kuka_orange", True),
        ("cyl", 0.0, 0.012, R12 + 0.006, "lbr_grey", False),  # ring hint at joint 2
    ],
    "lbr4p_link_3": [
        ("cyl", 0.0, 0.200, R34, "kuka_orange", True),
        ("sph", 0.200, R34, "kuka_orange", True),
        ("cyl", 0.0, 0.018, R34 + 0.004, "lbr_grey", False),
    ],
    "lbr4p_link_4": [
        ("sph", 0.0, R34, "kuka_orange", True),
        ("cyl", 0.0, 0.200, R34, "kuka_orange", True),
    ],
    "lbr4p_link_5": [
        ("cyl", 0.0, 0.080, R5, "kuka_orange", True),
        ("sph", 0.080, R5, "kuka_orange", True),
        ("cyl", 0.0, 0.018, R5 + 0.004, "lbr_grey", False),
    ],
    "lbr4p_link_6": [
        ("sph", 0.0, R5, "kuka_orange", True),
        ("cyl", 0.0, 0.0675, R6, "lbr_grey", True),
    ],
    "lbr4p_link_7": [
        ("cyl", 0.0, FLANGE_Z, R7, "flange_dark", True),
    ],
}


def f(x: float) -> str:
    """Shortest exact-enough decimal (repr round-trips the float)."""
    s = repr(float(x))
    return "0" if s in ("0.0", "-0.0") else s


def geometry_xml(link: str) -> list[str]:
    out: list[str] = []
    counters: dict[str, int] = {}
    for g in GEOMETRY.get(link, []):
        kind = g[0]
        counters[kind] = counters.get(kind, 0) + 1
        tag = f"{kind}{counters[kind]}"
        if kind == "cyl":
            _, z0, z1, r, mat, coll = g
            shape = f'<cylinder radius="{f(r)}" length="{f(round(z1 - z0, 12))}"/>'
            zc = round(0.5 * (z0 + z1), 12)
        else:
            _, zc, r, mat, coll = g
            shape = f'<sphere radius="{f(r)}"/>'
        origin = f'<origin xyz="0 0 {f(zc)}" rpy="0 0 0"/>'
        out += [
            f'    <visual name="{link}_visual_{tag}">',
            f"      {origin}",
            f"      <geometry>{shape}</geometry>",
            f'      <material name="{mat}"/>',
            "    </visual>",
        ]
        if coll:
            out += [
                f'    <collision name="{link}_collision_{tag}">',
                f"      {origin}",
                f"      <geometry>{shape}</geometry>",
                "    </collision>",
            ]
    return out


def inertial_xml(i: int) -> list[str]:
    ixx, iyy, izz, iyz = INERTIA[i]
    x, y, z = COM[i]
    return [
        "    <inertial>",
        f'      <origin xyz="{f(x)} {f(y)} {f(z)}" rpy="0 0 0"/>',
        f'      <mass value="{f(MASS[i])}"/>',
        f'      <inertia ixx="{f(ixx)}" ixy="0" ixz="0" iyy="{f(iyy)}" iyz="{f(iyz)}"'
        f' izz="{f(izz)}"/>',
        "    </inertial>",
    ]


def tiny_inertial() -> list[str]:
    """Negligible explicit inertial for the static links: keeps MuJoCo from computing their
    mass from the collision geoms' density (Pinocchio lumps it into the fixed universe)."""
    return [
        "    <inertial>",
        '      <origin xyz="0 0 0" rpy="0 0 0"/>',
        f'      <mass value="{f(STATIC_MASS)}"/>',
        f'      <inertia ixx="{f(STATIC_INERTIA)}" ixy="0" ixz="0" iyy="{f(STATIC_INERTIA)}"'
        f' iyz="0" izz="{f(STATIC_INERTIA)}"/>',
        "    </inertial>",
    ]


def fixed_joint(name: str, parent: str, child: str, z: float) -> list[str]:
    return [
        f'  <joint name="{name}" type="fixed">',
        f'    <parent link="{parent}"/>',
        f'    <child link="{child}"/>',
        f'    <origin xyz="0 0 {f(z)}" rpy="0 0 0"/>',
        "  </joint>",
    ]


def build() -> str:
    L: list[str] = [
        '<?xml version="1.0"?>',
        "<!-- KUKA LBR4p on a 0.3995 m pedestal. GENERATED by generate_urdf.py: do not edit by",
        "     hand. Kinematics reproduce the standard-DH chain of the thesis (eq. 4.2-4.3):",
        "     d = [0.2, 0, 0.4, 0, 0.39, 0, 0.078], a = 0,",
        "     alpha = [pi/2, -pi/2, pi/2, -pi/2, pi/2, -pi/2, 0], DH frame 0 at z = 0.51 m,",
        "     flange = DH frame 7. All link frames are parallel to base_link at q = 0.",
        "     Sources of every number: README.md next to this file. -->",
        '<robot name="lbr4p">',
        "",
        "  <!-- MuJoCo-only extension (ignored by other URDF parsers) -->",
        "  <mujoco>",
        '    <compiler discardvisual="false" fusestatic="false" balanceinertia="true"'
        ' strippath="false"/>',
        "  </mujoco>",
        "",
    ]
    for name, rgba in MATERIALS.items():
        L += [f'  <material name="{name}">', f'    <color rgba="{rgba}"/>', "  </material>"]
    L += [
        "",
        "  <!-- the robot's base frame (= world); no dynamics -->",
        '  <link name="base_link"/>',
        "",
        "  <!-- fixed pedestal: static, carries no dynamics (negligible inertial) -->",
        '  <link name="lbr4p_pedestal">',
        *tiny_inertial(),
        *geometry_xml("lbr4p_pedestal"),
        "  </link>",
        *fixed_joint("lbr4p_pedestal_joint", "base_link", "lbr4p_pedestal", 0.0),
        "",
        "  <!-- the arm's own base; its frame is DH frame 0 (joint 1's centre, 0.51 m up) -->",
        '  <link name="lbr4p_link_0">',
        *tiny_inertial(),
        *geometry_xml("lbr4p_link_0"),
        "  </link>",
        *fixed_joint("lbr4p_link_0_joint", "lbr4p_pedestal", "lbr4p_link_0", DH_BASE_Z),
    ]
    parent = "lbr4p_link_0"
    for i in range(7):
        link = f"lbr4p_link_{i + 1}"
        lim = math.radians(POS_LIMIT_DEG[i])
        L += [
            "",
            f'  <joint name="lbr4p_joint_{i + 1}" type="revolute">',
            f'    <parent link="{parent}"/>',
            f'    <child link="{link}"/>',
            f'    <origin xyz="0 0 {f(JOINT_Z[i])}" rpy="0 0 0"/>',
            f'    <axis xyz="{JOINT_AXIS[i]}"/>',
            f'    <limit lower="{f(-lim)}" upper="{f(lim)}"'
            f' velocity="{f(math.radians(VEL_LIMIT_DEG[i]))}" effort="{f(EFFORT[i])}"/>',
            f'    <dynamics damping="{f(DAMPING[i])}" friction="0"/>',
            "  </joint>",
            f'  <link name="{link}">',
            *inertial_xml(i),
            *geometry_xml(link),
            "  </link>",
        ]
        parent = link
    L += [
        "",
        "  <!-- end-effector frame = DH frame 7; no geometry, no inertial -->",
        *fixed_joint("lbr4p_flange_joint", "lbr4p_link_7", "lbr4p_flange", FLANGE_Z),
        '  <link name="lbr4p_flange"/>',
        "",
        "</robot>",
        "",
    ]
    return "\n".join(L)


if __name__ == "__main__":
    text = build()
    for out in OUTPUTS:
        out.write_text(text, encoding="utf-8")
        print(f"wrote {out}")
    readme = PACKAGE_DIR / "README.md"
    readme.write_text(README_NOTE + (HERE / "README.md").read_text(encoding="utf-8"), "utf-8")
    print(f"wrote {readme}")
