#!/usr/bin/env python3
"""Writes the built-in robots' URDFs for vtgen: robots/ur5e/arm.urdf (the UR5e arm, base to flange),
robots/ur5e_allegro/hand.urdf (a right Allegro hand v3) and robots/ur5e_robotiq_2f85/gripper.urdf (a
Robotiq 2F-85). Each robot's description mounts its hand on the arm's flange (`hand_urdf` +
`mount`).

The numbers are kinematic facts from public robot descriptions (UR standard DH parameters and
limits; Allegro joint axes, limits, link offsets, collision sizes and masses; the 2F-85's joint
origins, axes, limits and mimic couplings of its URDF in airo-models 0.0.12, its links' boxes
bounding that package's collision meshes); no XML was copied. The URDFs are the artefacts both
physics backends read; this script documents where every number comes from and regenerates them:
`python3 robots/ur5e_allegro/make_urdf.py`.
"""
import math
from pathlib import Path

out = []
w = out.append

# The real meshes of the built-in robots, drawn where the robot assets hold them
# (`scripts/robot-assets` fetches them from PyPI into package folders named allegro/, ur5e/ and
# robotiq_2f85/); without them each link is drawn from its primitive visuals (the descriptions'
# `drawn_meshes: optional`). Per link: (file, xyz, rpy, material or None for the file's own
# colours, scale).
MESH_VISUALS = {}


def mat4(xyz, rpy):
    """A URDF origin as a 4x4 matrix: R = Rz(yaw) Ry(pitch) Rx(roll), then the translation."""
    (r, p, y), (cr, sr, cp, sp, cy, sy) = rpy, (math.cos(rpy[0]), math.sin(rpy[0]), math.cos(rpy[1]),
                                                  math.sin(rpy[1]), math.cos(rpy[2]), math.sin(rpy[2]))
    return [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr, xyz[0]],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr, xyz[1]],
            [-sp, cp * sr, cp * cr, xyz[2]],
            [0.0, 0.0, 0.0, 1.0]]


def mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def inverse(m):
    rt = [[m[j][i] for j in range(3)] for i in range(3)]
    t = [-sum(rt[i][k] * m[k][3] for k in range(3)) for i in range(3)]
    return [rt[0] + [t[0]], rt[1] + [t[1]], rt[2] + [t[2]], [0.0, 0.0, 0.0, 1.0]]


def xyz_rpy(m):
    """The URDF origin of a rigid 4x4 matrix (checked by composing it back)."""
    pitch = math.asin(max(-1.0, min(1.0, -m[2][0])))
    if abs(math.cos(pitch)) > 1e-9:
        roll, yaw = math.atan2(m[2][1], m[2][2]), math.atan2(m[1][0], m[0][0])
    else:  # gimbal lock: yaw 0, roll from the remaining rotation
        roll, yaw = math.atan2(-m[1][2], m[1][1]), 0.0
    # Rounded to 1e-12 (m, rad): the products leave 1e-17 crumbs where there are zeros.
    xyz, rpy = [round(m[i][3], 12) + 0.0 for i in range(3)], [round(a, 12) + 0.0 for a in (roll, pitch, yaw)]
    back = mat4(xyz, rpy)
    assert all(abs(back[i][j] - m[i][j]) < 1e-12 for i in range(3) for j in range(4)), m
    return xyz, rpy


def box_inertia(m, x, y, z):
    return (m * (y * y + z * z) / 12, m * (x * x + z * z) / 12, m * (x * x + y * y) / 12)


def link(name, mass, geoms, com=(0, 0, 0)):
    """geoms: (kind, size, xyz, material, collides)."""
    w(f'  <link name="{name}">')
    if mass > 0:
        boxes = [g for g in geoms if g[0] == "box"]
        ixx, iyy, izz = box_inertia(mass, *boxes[0][1]) if boxes else (1e-5, 1e-5, 1e-5)
        w(f'    <inertial><origin xyz="{com[0]:.5f} {com[1]:.5f} {com[2]:.5f}"/><mass value="{mass}"/>'
          f'<inertia ixx="{ixx:.4e}" ixy="0" ixz="0" iyy="{iyy:.4e}" iyz="0" izz="{izz:.4e}"/></inertial>')
    for kind, size, xyz, material, collides in geoms:
        if kind == "box":
            g = f'<box size="{size[0]} {size[1]} {size[2]}"/>'
        elif kind == "sphere":
            g = f'<sphere radius="{size}"/>'
        else:
            g = f'<cylinder radius="{size[0]}" length="{size[1]}"/>'
        o = f'<origin xyz="{xyz[0]:.5f} {xyz[1]:.5f} {xyz[2]:.5f}"/>'
        w(f'    <visual>{o}<geometry>{g}</geometry><material name="{material}"/></visual>')
        if collides:
            w(f'    <collision>{o}<geometry>{g}</geometry></collision>')
    for file, xyz, rpy, material, scale in MESH_VISUALS.get(name, []):
        o = f'<origin xyz="{xyz[0]!r} {xyz[1]!r} {xyz[2]!r}" rpy="{rpy[0]!r} {rpy[1]!r} {rpy[2]!r}"/>'
        s = f' scale="{scale} {scale} {scale}"' if scale != 1 else ""
        m = f'<material name="{material}"/>' if material else ""
        w(f'    <visual>{o}<geometry><mesh filename="package://{file}"{s}/></geometry>{m}</visual>')
    w("  </link>")


def joint(name, kind, parent, child, xyz, rpy=(0, 0, 0), axis=None, lim=None, effort=0, velocity=0, mimic=None):
    w(f'  <joint name="{name}" type="{kind}">')
    w(f'    <parent link="{parent}"/><child link="{child}"/>')
    w(f'    <origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}" rpy="{rpy[0]} {rpy[1]} {rpy[2]}"/>')
    if axis:
        w(f'    <axis xyz="{axis[0]} {axis[1]} {axis[2]}"/>')
    if lim:
        w(f'    <limit lower="{lim[0]}" upper="{lim[1]}" effort="{effort}" velocity="{velocity}"/>')
    if mimic:
        w(f'    <mimic joint="{mimic[0]}" multiplier="{mimic[1]}" offset="0"/>')
    w("  </joint>")


def header(robot, what, notes, materials):
    w('<?xml version="1.0"?>')
    w(f"<!-- {what} for vtgen. Generated by robots/ur5e_allegro/make_urdf.py: do not edit.")
    w(f"     Units: metres, radians, kilograms.{notes} -->")
    w(f'<robot name="{robot}">')
    for name, rgba in materials:
        w(f'  <material name="{name}"><color rgba="{rgba}"/></material>')


def ur5e_header():
    header("ur5e", "The UR5e arm, base_link to flange", "", [("arm_grey", "0.62 0.64 0.67 1"), ("arm_blue", "0.18 0.38 0.62 1")])


def allegro_header():
    header("allegro_hand_right", "A right Allegro hand v3 on a 10 mm adapter (its root, hand_adapter)",
           " Sensor links <finger>_<phalanx>_pad: origin on the palmar\n     surface of the phalanx at mid-length, z pointing out of the finger (the tactile cameras).",
           [("hand_black", "0.2 0.2 0.2 1"), ("tip_white", "0.9 0.9 0.9 1")])


# The UR5e's visual meshes (airo-models 0.0.12, arms/ur5e/visual, OBJ + MTL) sit in the links of
# Universal Robots' ROS description (its ur5e.urdf): per link, the ROS joint origin leading to it
# and the mesh's visual origin there (xyz, rpy). Its base_link_inertia is our base_link (the DH
# base frame). The ROS link frames differ from our DH link frames by a fixed offset per link,
# found from both chains at q = 0 (both turn each joint about its local z, so it holds at any q).
H, PI = math.pi / 2, math.pi
ROS_CHAIN = [
    ("base_link", ((0, 0, 0), (0, 0, 0)), "base.obj", ((0, 0, 0), (0, 0, PI))),
    ("shoulder_pan_link", ((0, 0, 0.1625), (0, 0, 0)), "shoulder.obj", ((0, 0, 0), (0, 0, PI))),
    ("shoulder_lift_link", ((0, 0, 0), (H, 0, 0)), "upperarm.obj", ((0, 0, 0.138), (H, 0, -H))),
    ("elbow_link", ((-0.425, 0, 0), (0, 0, 0)), "forearm.obj", ((0, 0, 0.007), (H, 0, -H))),
    ("wrist_1_link", ((-0.3922, 0, 0.1333), (0, 0, 0)), "wrist1.obj", ((0, 0, -0.127), (H, 0, 0))),
    ("wrist_2_link", ((0, -0.0997, 0), (H, 0, 0)), "wrist2.obj", ((0, 0, -0.0997), (0, 0, 0))),
    ("wrist_3_link", ((0, 0, 0.0996), (H, PI, PI)), "wrist3.obj", ((0, 0, -0.0989), (H, 0, 0))),
]
# UR5e, standard DH (a, d, alpha) and link masses. Joint i+1's origin is joint i's fixed DH part:
# translation (a_i, 0, d_i) then rotation alpha_i about x; every joint turns about its local z.
DH = [(0.0, 0.1625, math.pi / 2, 3.761), (-0.425, 0.0, 0.0, 8.058), (-0.3922, 0.0, 0.0, 2.846),
      (0.0, 0.1333, math.pi / 2, 1.37), (0.0, 0.0997, -math.pi / 2, 1.3), (0.0, 0.0996, 0.0, 0.365)]
ARM = ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"]


def ur5e_mesh_visuals():
    """The UR5e meshes' origins in our link frames: (our link at q = 0)^-1 * (ROS link at q = 0) *
    (the ROS visual origin)."""
    ours, t, prev = {"base_link": mat4((0, 0, 0), (0, 0, 0))}, mat4((0, 0, 0), (0, 0, 0)), (0.0, 0.0, 0.0)
    for name, (a, d, alpha, _) in zip(ARM, DH):
        t = mul(t, mat4((prev[0], 0, prev[1]), (prev[2], 0, 0)))
        ours[f"{name}_link"], prev = t, (a, d, alpha)
    ros = mat4((0, 0, 0), (0, 0, 0))
    for link_name, (jxyz, jrpy), mesh, (vxyz, vrpy) in ROS_CHAIN:
        ros = mul(ros, mat4(jxyz, jrpy))
        xyz, rpy = xyz_rpy(mul(mul(inverse(ours[link_name]), ros), mat4(vxyz, vrpy)))
        MESH_VISUALS[link_name] = [(f"ur5e/visual/{mesh}", xyz, rpy, None, 1)]


def allegro_mesh_visuals():
    """The Allegro hand v4's STL meshes (example-robot-data 6.0.0, allegro_hand_description/meshes),
    each in its link's frame of that package's URDF, whose joint origins our hand uses unchanged;
    the fingertips at the tip joint (0.0267 m, thumb 0.0423 m along the distal link's z). The hand
    black, the fingertips white (the URDF's materials)."""
    black = lambda f, z=0.0: (f"allegro/meshes/{f}", (0, 0, z), (0, 0, 0), "hand_black", 1)
    tip = lambda f, z: (f"allegro/meshes/{f}", (0, 0, z), (0, 0, 0), "tip_white", 1)
    MESH_VISUALS["palm"] = [black("base_link.STL")]
    for p in ("ff", "mf", "rf"):
        MESH_VISUALS[f"{p}_base"] = [black("link_0.0.STL")]
        MESH_VISUALS[f"{p}_proximal"] = [black("link_1.0.STL")]
        MESH_VISUALS[f"{p}_medial"] = [black("link_2.0.STL")]
        MESH_VISUALS[f"{p}_distal"] = [black("link_3.0.STL"), tip("link_3.0_tip.STL", 0.0267)]
    MESH_VISUALS["th_base"] = [black("link_12.0_right.STL")]
    MESH_VISUALS["th_proximal"] = [black("link_13.0.STL")]
    MESH_VISUALS["th_medial"] = [black("link_14.0.STL")]
    MESH_VISUALS["th_distal"] = [black("link_15.0.STL"), tip("link_15.0_tip.STL", 0.0423)]


def robotiq_mesh_visuals():
    """The 2F-85's visual OBJs (airo-models 0.0.12, grippers/robotiq_2f_85/meshes/visual), each in
    its link's frame of that package's robotiq_2f_85.urdf (whose joint origins our gripper uses;
    its base_link_inertia is our gripper_body); the body in metres, the rest in millimetres."""
    part = lambda f, material, scale: (f"robotiq_2f85/visual/robotiq_arg2f_85_{f}.obj", (0, 0, 0), (0, 0, 0), material, scale)
    MESH_VISUALS["gripper_body"] = [part("base_link", "gripper_black", 1)]
    for side in ("left", "right"):
        MESH_VISUALS[f"{side}_outer_knuckle"] = [part("outer_knuckle", "knuckle_grey", 0.001)]
        MESH_VISUALS[f"{side}_outer_finger"] = [part("outer_finger", "gripper_black", 0.001)]
        MESH_VISUALS[f"{side}_inner_finger"] = [part("inner_finger", "gripper_black", 0.001)]
        MESH_VISUALS[f"{side}_inner_knuckle"] = [part("inner_knuckle", "gripper_black", 0.001)]


def ur5e():
    ARM_LIMITS = [(2 * math.pi, 150), (2 * math.pi, 150), (math.pi, 150), (2 * math.pi, 28), (2 * math.pi, 28), (2 * math.pi, 28)]
    link("base_link", 4.0, [("cylinder", (0.075, 0.09), (0, 0, 0.045), "arm_grey", True)])
    parent, prev = "base_link", (0.0, 0.0, 0.0)
    for i, (name, (a, d, alpha, mass)) in enumerate(zip(ARM, DH)):
        # Link geometry in the link frame (after the joint's rotation): the segment to (a, 0, d).
        geoms = []
        if abs(a) > 0:
            geoms.append(("box", (abs(a) + 0.09, 0.09, 0.09), (a / 2, 0, d), "arm_blue" if i == 1 else "arm_grey", True))
        if abs(d) > 0:
            geoms.append(("cylinder", (0.045, abs(d)), (0, 0, d / 2), "arm_grey", True))
        link(f"{name}_link", mass, geoms)
        limit, effort = ARM_LIMITS[i]
        joint(f"{name}_joint", "revolute", parent, f"{name}_link", (prev[0], 0, prev[1]), (prev[2], 0, 0), (0, 0, 1),
              (round(-limit, 6), round(limit, 6)), effort, round(math.pi, 6))
        parent, prev = f"{name}_link", (a, d, alpha)
    link("flange", 0.0, [])
    joint("flange_joint", "fixed", parent, "flange", (prev[0], 0, prev[1]), (prev[2], 0, 0))


def allegro():
    # Allegro right hand. Palm frame: +z toward the fingers, +y toward the index, palmar side +x. It sits
    # on a 10 mm adapter so that the palm's base (z = -0.095 in the palm frame) meets the adapter.
    link("hand_adapter", 0.05, [("cylinder", (0.032, 0.01), (0, 0, 0.005), "hand_black", True)])
    link("palm", 0.4154, [("box", (0.0408, 0.1130, 0.095), (-0.0093, 0, -0.0475), "hand_black", True)], com=(-0.0093, 0, -0.0475))
    joint("palm_joint", "fixed", "hand_adapter", "palm", (0, 0, 0.105))

    SECTION = (0.0196, 0.0275)  # link cross-section, x (palmar-dorsal) by y
    TIP_RADIUS = 0.012
    PHALANGES = ["proximal", "medial", "distal"]
    FINGERS = [
        # prefix, j0 origin, j0 rpy, j0 axis, base link geometry, j1 origin, joint axes j1..j3,
        # phalanx lengths (distal: to the fingertip sphere centre), limits j0..j3, masses j0..j3
        ("ff", (0, 0.0435, -0.001542), (-0.08726646, 0, 0), (0, 0, 1), ((0.0196, 0.0275, 0.0164), (0, 0, 0.0082)),
         (0, 0, 0.0164), [(0, 1, 0)] * 3, [0.054, 0.0384, 0.0267],
         [(-0.470, 0.470), (-0.196, 1.610), (-0.174, 1.709), (-0.227, 1.618)], [0.0119, 0.065, 0.0355, 0.0096]),
        ("mf", (0, 0, 0.0007), (0, 0, 0), (0, 0, 1), ((0.0196, 0.0275, 0.0164), (0, 0, 0.0082)),
         (0, 0, 0.0164), [(0, 1, 0)] * 3, [0.054, 0.0384, 0.0267],
         [(-0.470, 0.470), (-0.196, 1.610), (-0.174, 1.709), (-0.227, 1.618)], [0.0119, 0.065, 0.0355, 0.0096]),
        ("rf", (0, -0.0435, -0.001542), (0.08726646, 0, 0), (0, 0, 1), ((0.0196, 0.0275, 0.0164), (0, 0, 0.0082)),
         (0, 0, 0.0164), [(0, 1, 0)] * 3, [0.054, 0.0384, 0.0267],
         [(-0.470, 0.470), (-0.196, 1.610), (-0.174, 1.709), (-0.227, 1.618)], [0.0119, 0.065, 0.0355, 0.0096]),
        ("th", (-0.0182, 0.019333, -0.045987), (0, -1.65806279, -1.57079633), (-1, 0, 0),
         ((0.0358, 0.034, 0.0455), (-0.0179, 0.009, 0.0145)),
         (-0.027, 0.005, 0.0399), [(0, 0, 1), (0, 1, 0), (0, 1, 0)], [0.0177, 0.0514, 0.0423],
         [(0.263, 1.396), (-0.105, 1.163), (-0.189, 1.644), (-0.162, 1.719)], [0.0176, 0.0119, 0.038, 0.0388]),
    ]
    for p, j0_xyz, j0_rpy, j0_axis, (base_size, base_xyz), j1_xyz, axes, lengths, limits, masses in FINGERS:
        link(f"{p}_base", masses[0], [("box", base_size, base_xyz, "hand_black", True)])
        joint(f"{p}_joint_0", "revolute", "palm", f"{p}_base", j0_xyz, j0_rpy, j0_axis, limits[0], 0.7, 6.0)
        parent, origin = f"{p}_base", j1_xyz
        for k, phalanx in enumerate(PHALANGES):
            length = lengths[k]
            geoms = [("box", (SECTION[0], SECTION[1], length), (0, 0, length / 2), "hand_black", True)]
            if phalanx == "distal":
                geoms.append(("sphere", TIP_RADIUS, (0, 0, length), "tip_white", True))
            link(f"{p}_{phalanx}", masses[k + 1], geoms, com=(0, 0, length / 2))
            joint(f"{p}_joint_{k + 1}", "revolute", parent, f"{p}_{phalanx}", origin, (0, 0, 0), axes[k], limits[k + 1], 0.7, 6.0)
            # Tactile pad: palmar surface (+x) at mid-length; rpy (0, pi/2, 0) turns the pad's z to +x.
            # The distal pad spans the fingertip too (to the end of the tip sphere).
            sensing = length + (TIP_RADIUS if phalanx == "distal" else 0.0)
            link(f"{p}_{phalanx}_pad", 0.0, [])
            joint(f"{p}_{phalanx}_pad_joint", "fixed", f"{p}_{phalanx}", f"{p}_{phalanx}_pad",
                  (SECTION[0] / 2, 0, round(sensing / 2, 6)), (0, round(math.pi / 2, 8), 0))
            parent, origin = f"{p}_{phalanx}", (0, 0, length)


def robotiq_header():
    header("robotiq_2f85", "A Robotiq 2F-85 (its root, gripper_base, on a flange)",
           " grasp_frame: between the pads, +x the approach\n     direction, +y from the left pad to the right one. Sensor links <side>_pad: origin on the\n     inner face of the finger pad, z pointing at the other pad (the tactile cameras).",
           [("gripper_black", "0.1 0.1 0.1 1"), ("knuckle_grey", "0.79 0.82 0.93 1"), ("pad_grey", "0.9 0.9 0.9 1")])


def robotiq_2f85():
    # The 2F-85 on the flange (its base's z along the tool axis). Its base_link_inertia turns the
    # finger plane by -90 deg about z: the fingers close along the base's x.
    link("gripper_base", 0.0, [])
    link("gripper_body", 0.22652, [("box", (0.075, 0.0848, 0.09), (0, 0, 0.045), "gripper_black", True)], com=(0, 0, 0.03145))
    joint("gripper_body_joint", "fixed", "gripper_base", "gripper_body", (0, 0, 0), (0, 0, round(-math.pi / 2, 8)))
    # finger_joint drives the left outer knuckle; the other five moving joints mimic it, the
    # inner fingers with -1 so that the pads stay parallel (the real gripper's four-bar linkage).
    for side, sign, knuckle_joint in [("left", -1, "finger_joint"), ("right", 1, "right_outer_knuckle_joint")]:
        yaw = math.pi if side == "left" else 0.0
        mimic = None if side == "left" else ("finger_joint", 1)
        link(f"{side}_outer_knuckle", 0.00853, [("box", (0.024, 0.0463, 0.0229), (0, 0.0157, 0.0014), "knuckle_grey", True)])
        joint(knuckle_joint, "revolute", "gripper_body", f"{side}_outer_knuckle", (0, sign * 0.0306011, 0.054904), (0, 0, yaw),
              (1, 0, 0), (0, 0.8), 1000, 2.0, mimic)
        link(f"{side}_outer_finger", 0.02261, [("box", (0.027, 0.0181, 0.0591), (0, 0.0031, 0.0236), "gripper_black", True)])
        joint(f"{side}_outer_finger_joint", "fixed", f"{side}_outer_knuckle", f"{side}_outer_finger", (0, 0.0315, -0.0041))
        link(f"{side}_inner_finger", 0.0104, [("box", (0.015, 0.0299, 0.0505), (0, -0.009, 0.0193), "gripper_black", True)])
        joint(f"{side}_inner_finger_joint", "revolute", f"{side}_outer_finger", f"{side}_inner_finger", (0, 0.0061, 0.0471), (0, 0, 0),
              (1, 0, 0), (-0.8757, 0), 1000, 2.0, ("finger_joint", -1))
        link(f"{side}_inner_finger_pad", 0.005, [("box", (0.022, 0.00635, 0.0375), (0, 0, 0), "pad_grey", True)])
        joint(f"{side}_inner_finger_pad_joint", "fixed", f"{side}_inner_finger", f"{side}_inner_finger_pad", (0, -0.0220203, 0.03242))
        # The tactile pad: on the pad's inner face (local -y), z towards the other finger.
        link(f"{side}_pad", 0.0, [])
        joint(f"{side}_pad_joint", "fixed", f"{side}_inner_finger_pad", f"{side}_pad", (0, -0.003175, 0), (round(math.pi / 2, 8), 0, 0))
        # The inner knuckle closes the linkage; drawn, not collided (its box would be far fatter
        # than the real thin link).
        link(f"{side}_inner_knuckle", 0.02712, [("box", (0.039, 0.0491, 0.0554), (0, 0.0186, 0.0218), "gripper_black", False)])
        joint(f"{side}_inner_knuckle_joint", "revolute", "gripper_body", f"{side}_inner_knuckle", (0, sign * 0.0127, 0.06142),
              (0, 0, yaw), (1, 0, 0), (0, 0.8757), 1000, 2.0, ("finger_joint", 1))
    # Between the pads (open or closed: the pads move along y only), +x out of the gripper,
    # +y from the left pad to the right one: the palm frame's convention (+x towards the object).
    link("grasp_frame", 0.0, [])
    joint("grasp_frame_joint", "fixed", "gripper_base", "grasp_frame", (0, 0, 0.1303), (0, round(-math.pi / 2, 8), round(-math.pi / 2, 8)))


def write(name, header, body):
    out.clear()
    header()
    body()
    w("</robot>")
    (Path(__file__).parent / name).write_text("\n".join(out) + "\n")


# The arm's folder, robots/ur5e/ (not a robot on its own), and each hand in its robot's folder:
# robots/ur5e_allegro/ (this one) and robots/ur5e_robotiq_2f85/.
ur5e_mesh_visuals()
allegro_mesh_visuals()
robotiq_mesh_visuals()
write("../ur5e/arm.urdf", ur5e_header, ur5e)
write("hand.urdf", allegro_header, allegro)
write("../ur5e_robotiq_2f85/gripper.urdf", robotiq_header, robotiq_2f85)
