#pragma once

#include <filesystem>
#include <string>

#include "objscan/discovery/scenes.h"
#include "objscan/report/results.h"

/// Ground truth for a scan: the labelled scene mesh that comes with a synthetic recording, and the
/// evaluation of a scan's ranked hypotheses against it.
namespace objscan::pipeline {

/// The ground-truth scene mesh that comes with a source: X.scene_gt.ply beside X.oni, or
/// scene_gt.ply in a recording folder (objscan synth writes both); empty when there is none (and
/// for a sensor: `live` is one even where a folder of that name is at hand).
std::filesystem::path findGroundTruth(const std::string& source);

/// Checks, before any work, that `path` is a mesh whose vertices carry object ids; InputError
/// naming it otherwise.
void requireLabelledMesh(const std::filesystem::path& path);

/// Matches the ranked hypotheses of `run`'s first scene with the objects of the ground-truth mesh
/// (ids moved onto the scene mesh by the nearest surface within 1 cm; names from the
/// scene_gt.json beside it, when there is one): discovery::evaluateRanking.
report::Evaluation evaluateAgainstTruth(const std::filesystem::path& truth,
                                        const discovery::SceneDiscovery& run, double min_iou);

}  // namespace objscan::pipeline
