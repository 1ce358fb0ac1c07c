#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "objscan/core/pose.h"
#include "objscan/core/triangle_mesh.h"

/// Procedural household objects and building blocks for synthetic scenes. Every shape is built in
/// its own frame: metres, z up, resting on z = 0, centred on the z axis; outward normals; closed
/// surfaces unless said otherwise. Sizes follow real objects (a mug is 9.5 cm tall).
namespace objscan::capture::shapes {

/// An axis-aligned box with corners (-sx/2, -sy/2, 0) and (sx/2, sy/2, sz).
TriangleMesh box(float sx_m, float sy_m, float sz_m);

/// A surface of revolution about z. `profile` is a polyline of (radius, z) points traced with the
/// material on its left in the (r, z) plane, e.g. a solid cylinder: bottom centre -> out along the
/// bottom -> up the side -> in along the top to the axis. Normals then point outwards. Points with
/// radius 0 become single pole vertices.
TriangleMesh lathe(const std::vector<Eigen::Vector2f>& profile, int segments);

/// A tube of varying radius swept along a curve, with flat caps. `centre(t)` and `radius(t)` for t
/// in [0, 1]; `rings` samples along it, `segments` around.
TriangleMesh tube(const std::function<Eigen::Vector3f(float)>& centre,
                  const std::function<float(float)>& radius, int rings, int segments);

/// Appends `part` to `mesh` (positions, triangles; normals, colours, labels, weights and ignore
/// flags where both have them).
void append(TriangleMesh& mesh, const TriangleMesh& part);

/// The mesh moved by `offset_m`.
TriangleMesh translated(TriangleMesh mesh, const Eigen::Vector3f& offset_m);

/// The mesh with positions mapped by T (p -> T p) and normals rotated with it.
TriangleMesh transformed(TriangleMesh mesh, const Pose& T);

/// Moves a mesh so that it rests on z = 0, centred on the z axis (its xy bounding box centre).
void restOnGround(TriangleMesh& mesh);

/// Sets every vertex colour and label of `mesh`.
void paint(TriangleMesh& mesh, const Rgb8& color, std::int32_t label);

/// The built-in object set (DESIGN: mug with handle, bowl, box, can, bottle, ball, book,
/// keyboard-like slab, stapler-like shape, banana-like curved capsule, cup).
const std::vector<std::string>& builtinNames();

/// Small objects for harder scenes (1.5-4 cm across, or thin): a marble, a golf ball, a dice, a
/// toy brick with studs, a strawberry-like berry lying on its side, a spoon-like shape lying flat.
/// builtin() builds them too.
const std::vector<std::string>& smallNames();

/// A potted plant (pot, stems and leaves: 2 mm slabs), 20-35 cm tall, painted and labelled 0:
/// clutter that is not an object. `seed` places the leaves.
TriangleMesh plant(float variation, std::uint64_t seed);

/// Builds the named built-in object; `variation` in [0, 1) changes its proportions a little so
/// that two mugs in a scene differ. Throws std::invalid_argument for an unknown name.
TriangleMesh builtin(const std::string& name, float variation = 0.5f);

}  // namespace objscan::capture::shapes
