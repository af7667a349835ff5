// v4r - robust model-based object tracking. MIT licence.
//
// Built-in test objects and camera. The model texts are also stored as data/box.cao,
// data/ship_mockup.cao and data/flange.cao (a unit test checks that the copies are identical).
#include <cmath>

#include <Eigen/Geometry>

#include "v4r/synth/renderer.hpp"

namespace v4r::synth {

std::string box_cao() {
  return R"CAO(V1
# v4r built-in model "box": a 0.20 x 0.15 x 0.10 m box (x, y, z), origin at its centre.
# Units: metres. Faces list their points counter-clockwise seen from outside (normals point out).
# 3D points
8
-0.10 -0.075 -0.05   # 0
 0.10 -0.075 -0.05   # 1
 0.10  0.075 -0.05   # 2
-0.10  0.075 -0.05   # 3
-0.10 -0.075  0.05   # 4
 0.10 -0.075  0.05   # 5
 0.10  0.075  0.05   # 6
-0.10  0.075  0.05   # 7
# 3D lines
0
# Faces from 3D lines
0
# Faces from 3D points
6
4 0 3 2 1   # bottom (z = -0.05)
4 4 5 6 7   # top    (z = +0.05)
4 0 1 5 4   # front  (y = -0.075)
4 2 3 7 6   # back   (y = +0.075)
4 1 2 6 5   # right  (x = +0.10)
4 3 0 4 7   # left   (x = -0.10)
# 3D cylinders
0
# 3D circles
0
)CAO";
}

std::string ship_mockup_cao() {
  return R"CAO(V1
# v4r built-in model "ship_mockup": welded steel plates, after the mockup of a ship section in
# the V4R paper (section 6). A base plate 0.40 x 0.30 x 0.02 m, a longitudinal wall
# 0.36 x 0.02 x 0.12 m near one long side and a transverse wall 0.02 x 0.23 x 0.10 m at an
# off-centre position, butting against the longitudinal wall. The walls stand on the base plate;
# their hidden bottom faces (and the transverse wall's end against the longitudinal wall) are
# left out. The walls are inset from the plate's borders and the transverse wall is lower, so
# that no two adjacent faces are coplanar: every model edge is a visible image edge.
# Origin at the centre of the base plate's top face, z up. Units: metres.
# Faces list their points counter-clockwise seen from outside (normals point out).
# 3D points
24
# base plate: x in [-0.20, 0.20], y in [-0.15, 0.15], z in [-0.02, 0]
-0.20 -0.15 -0.02   # 0
 0.20 -0.15 -0.02   # 1
 0.20  0.15 -0.02   # 2
-0.20  0.15 -0.02   # 3
-0.20 -0.15  0.00   # 4
 0.20 -0.15  0.00   # 5
 0.20  0.15  0.00   # 6
-0.20  0.15  0.00   # 7
# longitudinal wall: x in [-0.18, 0.18], y in [0.10, 0.12], z in [0, 0.12]
-0.18  0.10  0.00   # 8
 0.18  0.10  0.00   # 9
 0.18  0.12  0.00   # 10
-0.18  0.12  0.00   # 11
-0.18  0.10  0.12   # 12
 0.18  0.10  0.12   # 13
 0.18  0.12  0.12   # 14
-0.18  0.12  0.12   # 15
# transverse wall: x in [0.06, 0.08], y in [-0.13, 0.10], z in [0, 0.10]
 0.06 -0.13  0.00   # 16
 0.08 -0.13  0.00   # 17
 0.08  0.10  0.00   # 18
 0.06  0.10  0.00   # 19
 0.06 -0.13  0.10   # 20
 0.08 -0.13  0.10   # 21
 0.08  0.10  0.10   # 22
 0.06  0.10  0.10   # 23
# 3D lines
0
# Faces from 3D lines
0
# Faces from 3D points
15
4 0 3 2 1       # base bottom (z = -0.02)
4 4 5 6 7       # base top    (z = 0)
4 0 1 5 4       # base front  (y = -0.15)
4 2 3 7 6       # base back   (y = +0.15)
4 1 2 6 5       # base right  (x = +0.20)
4 3 0 4 7       # base left   (x = -0.20)
4 12 13 14 15   # longitudinal wall top   (z = 0.12)
4 8 9 13 12     # longitudinal wall front (y = 0.10)
4 10 11 15 14   # longitudinal wall back  (y = 0.12)
4 9 10 14 13    # longitudinal wall right (x = +0.18)
4 11 8 12 15    # longitudinal wall left  (x = -0.18)
4 20 21 22 23   # transverse wall top   (z = 0.10)
4 16 17 21 20   # transverse wall end   (y = -0.13)
4 17 18 22 21   # transverse wall right (x = 0.08)
4 19 16 20 23   # transverse wall left  (x = 0.06)
# 3D cylinders
0
# 3D circles
0
)CAO";
}

std::string flange_cao() {
  return R"CAO(V1
# v4r built-in model "flange": a square steel plate 0.20 x 0.20 x 0.02 m with a cylinder
# (radius 0.05 m, height 0.06 m, axis z) standing on the centre of its top face.
# Origin at the centre of the plate's top face, z up. Units: metres.
# Faces list their points counter-clockwise seen from outside (normals point out).
# The cylinder is a .cao cylinder (2 axis points and a radius). ViSP tracks a .cao cylinder by
# its two limb lines only and needs its rims as two extra "3D circles" (radius, centre point,
# 2 points in the rim's plane); v4r's reader adds both rims of every cylinder as circle arcs,
# so they are not listed again here (that would duplicate them).
# 3D points
10
# plate: x in [-0.10, 0.10], y in [-0.10, 0.10], z in [-0.02, 0]
-0.10 -0.10 -0.02   # 0
 0.10 -0.10 -0.02   # 1
 0.10  0.10 -0.02   # 2
-0.10  0.10 -0.02   # 3
-0.10 -0.10  0.00   # 4
 0.10 -0.10  0.00   # 5
 0.10  0.10  0.00   # 6
-0.10  0.10  0.00   # 7
# cylinder axis: bottom (on the plate) and top centre
 0.00  0.00  0.00   # 8
 0.00  0.00  0.06   # 9
# 3D lines
0
# Faces from 3D lines
0
# Faces from 3D points
6
4 0 3 2 1   # plate bottom (z = -0.02)
4 4 5 6 7   # plate top    (z = 0)
4 0 1 5 4   # plate front  (y = -0.10)
4 2 3 7 6   # plate back   (y = +0.10)
4 1 2 6 5   # plate right  (x = +0.10)
4 3 0 4 7   # plate left   (x = -0.10)
# 3D cylinders
1
8 9 0.05   # axis from point 8 to point 9, radius 0.05
# 3D circles
0
)CAO";
}

std::string ship_section_cao() {
  return R"CAO(V1
# v4r built-in model "ship_section": a denser welded section for the timing benchmark (20-40
# visible features): a base plate 0.40 x 0.30 x 0.02 m, two longitudinal walls 0.36 x 0.02 m
# (port 0.12 m high, starboard 0.10 m) inset from its long sides, and three transverse frames
# 0.02 m thick and 0.07 m high between them, butting against both walls. Hidden faces (the walls'
# and frames' bottoms, the frames' ends against the walls) are left out. Heights differ so that no
# two adjacent faces are coplanar.
# Origin at the centre of the base plate's top face, z up. Units: metres.
# Faces list their points counter-clockwise seen from outside (normals point out).
# 3D points
48
# base plate: x in [-0.20, 0.20], y in [-0.15, 0.15], z in [-0.02, 0.00]
-0.20 -0.15 -0.02   # 0
 0.20 -0.15 -0.02   # 1
 0.20  0.15 -0.02   # 2
-0.20  0.15 -0.02   # 3
-0.20 -0.15  0.00   # 4
 0.20 -0.15  0.00   # 5
 0.20  0.15  0.00   # 6
-0.20  0.15  0.00   # 7
# port wall: x in [-0.18, 0.18], y in [0.10, 0.12], z in [0.00, 0.12]
-0.18  0.10  0.00   # 8
 0.18  0.10  0.00   # 9
 0.18  0.12  0.00   # 10
-0.18  0.12  0.00   # 11
-0.18  0.10  0.12   # 12
 0.18  0.10  0.12   # 13
 0.18  0.12  0.12   # 14
-0.18  0.12  0.12   # 15
# starboard wall: x in [-0.18, 0.18], y in [-0.12, -0.10], z in [0.00, 0.10]
-0.18 -0.12  0.00   # 16
 0.18 -0.12  0.00   # 17
 0.18 -0.10  0.00   # 18
-0.18 -0.10  0.00   # 19
-0.18 -0.12  0.10   # 20
 0.18 -0.12  0.10   # 21
 0.18 -0.10  0.10   # 22
-0.18 -0.10  0.10   # 23
# frame 1: x in [-0.12, -0.10], y in [-0.10, 0.10], z in [0.00, 0.07]
-0.12 -0.10  0.00   # 24
-0.10 -0.10  0.00   # 25
-0.10  0.10  0.00   # 26
-0.12  0.10  0.00   # 27
-0.12 -0.10  0.07   # 28
-0.10 -0.10  0.07   # 29
-0.10  0.10  0.07   # 30
-0.12  0.10  0.07   # 31
# frame 2: x in [-0.01, 0.01], y in [-0.10, 0.10], z in [0.00, 0.07]
-0.01 -0.10  0.00   # 32
 0.01 -0.10  0.00   # 33
 0.01  0.10  0.00   # 34
-0.01  0.10  0.00   # 35
-0.01 -0.10  0.07   # 36
 0.01 -0.10  0.07   # 37
 0.01  0.10  0.07   # 38
-0.01  0.10  0.07   # 39
# frame 3: x in [0.10, 0.12], y in [-0.10, 0.10], z in [0.00, 0.07]
 0.10 -0.10  0.00   # 40
 0.12 -0.10  0.00   # 41
 0.12  0.10  0.00   # 42
 0.10  0.10  0.00   # 43
 0.10 -0.10  0.07   # 44
 0.12 -0.10  0.07   # 45
 0.12  0.10  0.07   # 46
 0.10  0.10  0.07   # 47
# 3D lines
0
# Faces from 3D lines
0
# Faces from 3D points
25
4 0 3 2 1       # base plate bottom (z = -0.02)
4 4 5 6 7       # base plate top (z = +0.00)
4 0 1 5 4       # base plate front (y = -0.15)
4 2 3 7 6       # base plate back (y = +0.15)
4 1 2 6 5       # base plate right (x = +0.20)
4 3 0 4 7       # base plate left (x = -0.20)
4 12 13 14 15   # port wall top (z = +0.12)
4 8 9 13 12     # port wall front (y = +0.10)
4 10 11 15 14   # port wall back (y = +0.12)
4 9 10 14 13    # port wall right (x = +0.18)
4 11 8 12 15    # port wall left (x = -0.18)
4 20 21 22 23   # starboard wall top (z = +0.10)
4 16 17 21 20   # starboard wall front (y = -0.12)
4 18 19 23 22   # starboard wall back (y = -0.10)
4 17 18 22 21   # starboard wall right (x = +0.18)
4 19 16 20 23   # starboard wall left (x = -0.18)
4 28 29 30 31   # frame 1 top (z = +0.07)
4 25 26 30 29   # frame 1 right (x = -0.10)
4 27 24 28 31   # frame 1 left (x = -0.12)
4 36 37 38 39   # frame 2 top (z = +0.07)
4 33 34 38 37   # frame 2 right (x = +0.01)
4 35 32 36 39   # frame 2 left (x = -0.01)
4 44 45 46 47   # frame 3 top (z = +0.07)
4 41 42 46 45   # frame 3 right (x = +0.12)
4 43 40 44 47   # frame 3 left (x = +0.10)
# 3D cylinders
0
# 3D circles
0
)CAO";
}

std::string sponge_cao() {
  return R"CAO(V1
# A green household sponge as a box (the V4R paper's grasping example): 0.11 x 0.07 x 0.045 m
# (x, y, z), origin at its centre. Every face carries colour=R,G,B (0..1), which the detector's
# colour stage searches at 1/4 resolution before its edge templates (README, "Colour regions").
# 3D points
8
-0.055 -0.035 -0.0225   # 0
 0.055 -0.035 -0.0225   # 1
 0.055  0.035 -0.0225   # 2
-0.055  0.035 -0.0225   # 3
-0.055 -0.035  0.0225   # 4
 0.055 -0.035  0.0225   # 5
 0.055  0.035  0.0225   # 6
-0.055  0.035  0.0225   # 7
# 3D lines
0
# Faces from 3D lines
0
# Faces from 3D points
6
4 0 3 2 1 name=bottom colour=0.2,0.6,0.1
4 4 5 6 7 name=top colour=0.2,0.6,0.1
4 0 1 5 4 name=front colour=0.2,0.6,0.1
4 2 3 7 6 name=back colour=0.2,0.6,0.1
4 1 2 6 5 name=right colour=0.2,0.6,0.1
4 3 0 4 7 name=left colour=0.2,0.6,0.1
# 3D cylinders
0
# 3D circles
0
)CAO";
}

geometry::PinholeCamera default_camera() {
  geometry::PinholeCamera cam;
  cam.width = 640;
  cam.height = 480;
  cam.fx = 600.0;
  cam.fy = 600.0;
  cam.cx = 319.5;
  cam.cy = 239.5;
  cam.dist = {-0.05, 0.01, 0.0, 0.0, 0.0};
  return cam;
}

}  // namespace v4r::synth
