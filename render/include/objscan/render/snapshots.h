#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "objscan/core/intrinsics.h"
#include "objscan/core/pose.h"
#include "objscan/core/trajectory.h"
#include "objscan/core/triangle_mesh.h"

/// Pictures of discovery's results, rendered off-screen (OSMesa): the scene with the top
/// hypotheses painted in their rank colours (core/palette.h) and labelled with their rank, a
/// close-up of each, and a contact sheet of the close-ups.
namespace objscan::render {

/// A hypothesis to paint: its rank (1-based), score, and vertices of the scene mesh.
struct PaintedHypothesis {
  std::size_t rank = 0;
  double score = 0.0;
  std::vector<std::int32_t> vertices;
  /// The score is an object score (discovery's object set ranks by it), captioned so.
  bool object_score = false;
  /// closeUp draws the rank in a corner (off for segments that are not ranked hypotheses).
  bool show_rank = true;
};

/// Where the overview camera comes from.
enum class ViewKind {
  kAuto,          ///< kTrajectory when a trajectory is given, else kThreeQuarter
  kTrajectory,    ///< where the sensor mostly looked from (its mean pose), pulled back to fit
  kThreeQuarter,  ///< 45 degrees round and 35 degrees above the side the surfaces face
  kTop,           ///< straight down onto the dominant plane
};

/// "auto", "trajectory", "three-quarter", "top"; std::invalid_argument for anything else.
ViewKind parseViewKind(const std::string& name);
const char* toString(ViewKind kind);

/// A camera: its pose (x right, y down, z forward) and image.
struct SnapshotView {
  Pose T_W_C = Pose::Identity();
  Intrinsics intrinsics;
  ViewKind kind = ViewKind::kThreeQuarter;  ///< the kind actually used (never kAuto)
};

/// The world's up direction as the scene shows it: the axis of the dominant surface orientation
/// (the eigenvector of the area-weighted normal scatter with the largest eigenvalue: the table or
/// the floor in the scenes objscan is for), turned towards the side the surfaces face. Throws
/// std::invalid_argument for a mesh without a triangle of positive area.
Eigen::Vector3f sceneUp(const TriangleMesh& mesh);

/// The overview camera for an image of width x height with a 60 degree horizontal field of view.
/// Its direction comes from `kind` (`trajectory` may be null or empty: kAuto then means
/// kThreeQuarter, kTrajectory is an std::invalid_argument); its position is moved along its own
/// axes until every vertex of the hypotheses is in the picture with a margin, and of the scene's
/// vertices at most 2 % lie beyond each edge.
SnapshotView overviewView(const TriangleMesh& scene, const Trajectory* trajectory,
                          const std::vector<PaintedHypothesis>& hypotheses, int width, int height,
                          ViewKind kind = ViewKind::kAuto);

/// One rendered picture.
struct Snapshot {
  cv::Mat bgr;  ///< CV_8UC3, B, G, R order (encodePng's colour order)
  /// CV_32SC1: the rank of the hypothesis painted at each pixel, 0 where the scene (or nothing) is.
  cv::Mat ranks;
  /// The ranks whose label could be placed (visible in the picture), in rank order.
  std::vector<std::size_t> labelled;
};

/// Renders one scene with its hypotheses painted, from any number of cameras. The scene keeps
/// its colours, paled and desaturated so that the painted hypotheses stand out; a scene without
/// colours is light grey. Where hypotheses share vertices the better rank is painted. Not
/// thread-safe (OSMesa contexts belong to their thread).
class SnapshotRenderer {
 public:
  /// Throws std::invalid_argument when the mesh fails validate() or a hypothesis names a vertex
  /// it does not have or has rank 0; std::runtime_error when OSMesa cannot render.
  SnapshotRenderer(const TriangleMesh& scene, std::vector<PaintedHypothesis> hypotheses);
  ~SnapshotRenderer();
  SnapshotRenderer(const SnapshotRenderer&) = delete;
  SnapshotRenderer& operator=(const SnapshotRenderer&) = delete;

  /// The scene from `view`, each hypothesis outlined and labelled with its rank at its most
  /// interior visible pixel.
  Snapshot overview(const SnapshotView& view);

  /// A width x height close-up of hypothesis `index` (into the constructor's list): looked at
  /// from the side nearest `overview`'s direction from which most of it is visible, filling about
  /// two thirds of the picture, with its rank in the corner.
  Snapshot closeUp(std::size_t index, const SnapshotView& overview, int width, int height);

  const std::vector<PaintedHypothesis>& hypotheses() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A grid of close-ups (all the same size), each captioned with its rank and score; `columns` 0
/// picks about a 4:3 grid. Throws std::invalid_argument when the counts differ or the images'
/// sizes do.
cv::Mat contactSheet(const std::vector<cv::Mat>& closeups,
                     const std::vector<PaintedHypothesis>& hypotheses, int columns = 0);

}  // namespace objscan::render
