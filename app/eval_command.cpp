#include "eval_command.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <utility>

#include <regex.h>

#include <nlohmann/json.hpp>

#include "exit_codes.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/output_folder.h"
#include "objscan/core/progress.h"
#include "objscan/discovery/evaluation.h"
#include "objscan/discovery/scenes.h"
#include "objscan/report/results_io.h"

namespace objscan::app {
namespace {

namespace fs = std::filesystem;
using discovery::LabelledSegments;
using discovery::SceneDiscovery;

/// The labelled scenes through discovery's one entry point (no model: the average score).
SceneDiscovery labelledScenes(const std::vector<fs::path>& arguments,
                              const discovery::DiscoveryConfig& config,
                              const std::optional<fs::path>& catalog,
                              const discovery::SceneReading& read,
                              std::optional<discovery::ObjectnessModel> model = std::nullopt) {
  config.validate();
  std::vector<discovery::SceneInput> scenes;
  discovery::SceneReading reading = read;
  reading.labelled = true;
  reading.hash = catalog.has_value();
  {
    ProgressBar progress("reading scenes", arguments.size());
    for (const fs::path& a : arguments) {
      scenes.push_back(discovery::loadScene(a, reading));
      progress.advance();
    }
  }
  discovery::SceneDiscoveryOptions options;
  options.config = config;
  options.catalog = catalog;
  options.model = std::move(model);
  return discovery::discoverScenes(std::move(scenes), options);
}

/// Label thresholds: the paper's 0.7 first, then 0.5 and 0.8 as well.
constexpr double kLabelIous[] = {0.7, 0.5, 0.8};

struct Recall {
  std::string csv;  ///< per object: scene, id, vertices, best IoU of any candidate / hypothesis
  std::size_t objects = 0;
  std::size_t candidates_05 = 0, candidates_07 = 0;  ///< matched by any filtered candidate
  std::size_t hypotheses_05 = 0, hypotheses_07 = 0;  ///< by any candidate kept by suppression
};

Recall recallTable(const SceneDiscovery& set, const LabelledSegments& kept) {
  Recall r;
  for (const discovery::ObjectRecall& o : discovery::objectRecall(set, kept)) {
    std::ostringstream row;
    row << set.scenes[o.scene].name << ',' << o.object_id << ',' << o.vertices << ','
        << o.best_candidate_iou << ',' << o.best_hypothesis_iou << '\n';
    r.csv += row.str();
    ++r.objects;
    r.candidates_05 += o.best_candidate_iou >= 0.5;
    r.candidates_07 += o.best_candidate_iou >= 0.7;
    r.hypotheses_05 += o.best_hypothesis_iou >= 0.5;
    r.hypotheses_07 += o.best_hypothesis_iou >= 0.7;
  }
  return r;
}

double share(std::size_t a, std::size_t b) { return b ? static_cast<double>(a) / b : 0.0; }

std::string segmentsCsv(const SceneDiscovery& set, const LabelledSegments& segs) {
  std::ostringstream csv;
  csv << std::setprecision(6) << "scene,object_id,iou";
  for (const char* name : discovery::kMeasureNames) csv << ',' << name;
  csv << '\n';
  for (std::size_t i = 0; i < segs.measures.size(); ++i) {
    csv << set.scenes[segs.scene[i]].name << ',' << segs.matches[i].object_id << ','
        << segs.matches[i].iou;
    for (double v : discovery::measureValues(segs.measures[i])) {
      csv << ',';
      if (std::isfinite(v)) csv << v;
    }
    csv << '\n';
  }
  return csv.str();
}

/// hypotheses.csv: the hypotheses in discover's order (every scene's objects, then the
/// alternatives), each with the ground-truth object it overlaps most (0: none), that IoU, and the
/// share of its vertices the labels say nothing about (a hand-labelled scene's plant or lamp; 0
/// without an ignore mask), so a scene's wrong answers near the top of its list can be found and
/// looked at. `rank` counts within the scene from 1 (hypotheses.json's counts across scenes);
/// `object_rank` is the place in the object set (0: an alternative, or every row without the
/// object set). Matched against the object parts where the truth has whole objects too.
std::string hypothesesCsv(const SceneDiscovery& set) {
  std::ostringstream csv;
  csv << std::setprecision(6)
      << "scene,rank,object_rank,vertices,score,object_score,footing,rise_m,object_id,iou,"
         "ignored\n";
  const auto number = [&](double v) {
    if (std::isfinite(v)) csv << v;
  };
  std::vector<std::size_t> rank(set.scenes.size(), 0);
  for (const discovery::RankedHypothesis& r : set.ranked) {
    const discovery::Hypothesis& h = r.hypothesis;
    const discovery::GroundTruthObjects& truth = set.scenes[r.scene].truth.value();
    const discovery::ObjectMatch m = truth.bestMatch(h.segment.vertices);
    csv << set.scenes[r.scene].name << ',' << ++rank[r.scene] << ',' << h.object_rank << ','
        << h.segment.vertices.size() << ',';
    number(h.score);
    csv << ',';
    number(h.object_score);
    csv << ',' << discovery::toString(h.context.footing) << ',';
    number(h.context.rise_m);
    csv << ',' << m.object_id << ',' << m.iou << ',' << truth.ignoredShare(h.segment.vertices)
        << '\n';
  }
  return csv.str();
}

/// The protocol with segments labelled at `iou`; its CSVs and plot into OUT, its APs into
/// `summary` and on stdout. False when the labels at this IoU cannot be evaluated (warned).
bool evaluateAtIou(const EvalCommandOptions& options, const discovery::EvalConfig& eval,
                   const LabelledSegments& segs, double iou, nlohmann::json& summary) {
  const std::vector<int> labels = segs.labels(iou);
  discovery::EvalConfig config = eval;
  // The full protocol at the paper's threshold; the others for the combinations only.
  config.ablation = eval.ablation && iou == 0.7;
  const auto objects = static_cast<std::size_t>(std::count(labels.begin(), labels.end(), 1));
  std::printf("\nlabel: object at IoU >= %.1f: %zu of %zu segments\n", iou, objects, labels.size());
  discovery::EvalResult result;
  try {
    ProgressBar progress("evaluating, IoU " + std::to_string(iou).substr(0, 3),
                         static_cast<std::size_t>(config.splits));
    result = discovery::evaluate(segs.measures, labels, config, [&] { progress.advance(); });
  } catch (const std::invalid_argument& e) {
    if (iou == 0.7) throw;  // the paper's labels: nothing to report without them
    log::warning("labels at IoU " + std::to_string(iou).substr(0, 3) + ": " + e.what());
    return false;
  }
  std::ostringstream suffix;
  suffix << "_iou" << std::lround(iou * 10);
  const std::string tag = iou == 0.7 ? "" : suffix.str();
  discovery::writeEvalCsv(result, options.out / ("pr_curves" + tag + ".csv"),
                          options.out / ("ap" + tag + ".csv"));
  discovery::writePrPlot(result, options.out / ("pr_curves" + tag + ".png"));
  nlohmann::json aps;
  for (const auto* list : {&result.methods, &result.ablation}) {
    for (const discovery::MethodResult& m : *list) {
      std::printf("  %-36s AP %.3f +- %.3f\n", m.name.c_str(), m.ap_mean, m.ap_sd);
      aps[m.name] = {{"ap", m.ap_mean}, {"sd", m.ap_sd}};
    }
  }
  summary["label_iou_" + suffix.str().substr(4)] = {{"objects", objects}, {"ap", aps}};
  return true;
}

/// recall.csv and objects.csv, the recall into `summary` and on stdout.
void writeRecall(const fs::path& out, const Recall& recall, nlohmann::json& summary) {
  summary["object_recall"] = {{"objects", recall.objects},
                              {"candidates_iou_0.5", share(recall.candidates_05, recall.objects)},
                              {"candidates_iou_0.7", share(recall.candidates_07, recall.objects)},
                              {"hypotheses_iou_0.5", share(recall.hypotheses_05, recall.objects)},
                              {"hypotheses_iou_0.7", share(recall.hypotheses_07, recall.objects)}};
  std::ostringstream csv;
  csv << "pool,iou,matched,objects,recall\n";
  const auto row = [&](const char* pool, const char* iou, std::size_t matched) {
    csv << pool << ',' << iou << ',' << matched << ',' << recall.objects << ','
        << share(matched, recall.objects) << '\n';
  };
  row("candidates", "0.5", recall.candidates_05);
  row("candidates", "0.7", recall.candidates_07);
  row("hypotheses", "0.5", recall.hypotheses_05);
  row("hypotheses", "0.7", recall.hypotheses_07);
  writeFileAtomically(out / "recall.csv", csv.str());
  writeFileAtomically(
      out / "objects.csv",
      "scene,object_id,vertices,best_candidate_iou,best_hypothesis_iou\n" + recall.csv);
  std::printf(
      "\nobject recall %zu objects: any candidate %.1f %% at IoU 0.5, %.1f %% at 0.7; "
      "after suppression %.1f %% and %.1f %%\n",
      recall.objects, 100 * share(recall.candidates_05, recall.objects),
      100 * share(recall.candidates_07, recall.objects),
      100 * share(recall.hypotheses_05, recall.objects),
      100 * share(recall.hypotheses_07, recall.objects));
}

/// A --category: its name and its pattern, a POSIX extended regular expression that must match a
/// scene's whole file name. (POSIX's regcomp rather than std::regex: GCC 12 reports false
/// maybe-uninitialized warnings inside std::regex in the sanitizer build, where they are errors.)
class Category {
 public:
  Category(std::string name, const std::string& pattern) : name_(std::move(name)) {
    const std::string whole = "^(" + pattern + ")$";
    if (const int code = regcomp(&regex_, whole.c_str(), REG_EXTENDED | REG_NOSUB); code != 0) {
      char why[256];
      regerror(code, &regex_, why, sizeof why);
      throw std::invalid_argument("--category " + name_ + "=" + pattern +
                                  ": not a regular expression (" + why + ")");
    }
  }
  Category(const Category&) = delete;
  Category& operator=(const Category&) = delete;
  ~Category() { regfree(&regex_); }

  const std::string& name() const { return name_; }
  bool matches(const std::string& file) const {
    return regexec(&regex_, file.c_str(), 0, nullptr, 0) == 0;
  }

 private:
  std::string name_;
  regex_t regex_{};
};

std::vector<std::unique_ptr<Category>> parseCategories(const std::vector<std::string>& specs) {
  std::vector<std::unique_ptr<Category>> out;
  for (const std::string& spec : specs) {
    const std::size_t eq = spec.find('=');
    if (eq == 0 || eq == std::string::npos || eq + 1 == spec.size()) {
      throw std::invalid_argument("--category " + spec + ": expected NAME=REGEX");
    }
    out.push_back(std::make_unique<Category>(spec.substr(0, eq), spec.substr(eq + 1)));
  }
  return out;
}

std::string categoryOf(const std::vector<std::unique_ptr<Category>>& categories,
                       const std::string& scene) {
  const std::string file = fs::path(scene).filename().string();
  for (const auto& c : categories) {
    if (c->matches(file)) return c->name();
  }
  return "other";
}

/// Means over the scenes with objects.
struct SceneMeans {
  std::size_t scenes = 0, objects = 0;
  double recall_05 = 0, recall_07 = 0, ap_05 = 0, ap_07 = 0;
  void add(const discovery::SceneRecall& r) {
    if (r.objects == 0) return;
    ++scenes;
    objects += r.objects;
    recall_05 += r.recall_05;
    recall_07 += r.recall_07;
    ap_05 += r.ap_05;
    ap_07 += r.ap_07;
  }
  nlohmann::json json() const {
    const double n = scenes ? static_cast<double>(scenes) : 1.0;
    return {{"scenes", scenes},
            {"objects", objects},
            {"recall_0.5", recall_05 / n},
            {"recall_0.7", recall_07 / n},
            {"ap_0.5", ap_05 / n},
            {"ap_0.7", ap_07 / n}};
  }
  void print(const std::string& label) const {
    const double n = scenes ? static_cast<double>(scenes) : 1.0;
    std::printf(
        "  %-22s %3zu scenes %4zu objects  recall@0.5 %.3f  @0.7 %.3f  AP@0.5 %.3f  @0.7 %.3f\n",
        label.c_str(), scenes, objects, recall_05 / n, recall_07 / n, ap_05 / n, ap_07 / n);
  }
};

/// scenes.csv and the per-scene means (all scenes, each category; object parts and, where the
/// truth has them, whole objects) into `summary` and on stdout.
void writeSceneFigures(const fs::path& out, const SceneDiscovery& set,
                       const std::vector<std::unique_ptr<Category>>& categories,
                       nlohmann::json& summary) {
  std::ostringstream csv;
  csv << std::setprecision(6)
      << "scene,category,truth,objects,hypotheses,recall_0.5,recall_0.7,ap_0.5,ap_0.7\n";
  std::printf("\nper-scene means (discover's ranking):\n");
  bool any_whole = false;
  for (const discovery::DiscoveredScene& s : set.scenes) any_whole |= s.whole_objects.has_value();
  for (const bool whole : {false, true}) {
    if (whole && !any_whole) break;
    const char* truth = whole ? "whole_objects" : "objects";
    SceneMeans all;
    std::map<std::string, SceneMeans> by_category;
    for (const discovery::SceneRecall& r : discovery::sceneRecall(set, whole)) {
      const discovery::DiscoveredScene& scene = set.scenes[r.scene];
      const std::string category = categoryOf(categories, scene.name);
      all.add(r);
      by_category[category].add(r);
      csv << scene.name << ',' << category << ',' << truth << ',' << r.objects << ','
          << scene.hypotheses << ',' << r.recall_05 << ',' << r.recall_07 << ',' << r.ap_05 << ','
          << r.ap_07 << '\n';
    }
    const std::string prefix = whole ? "whole objects" : (any_whole ? "object parts" : "objects");
    all.print(prefix);
    nlohmann::json j = all.json();
    if (by_category.size() > 1 || !categories.empty()) {
      for (const auto& [name, means] : by_category) {
        means.print("  " + name);
        j["categories"][name] = means.json();
      }
    }
    summary[std::string("per_scene_") + truth] = j;
  }
  writeFileAtomically(out / "scenes.csv", csv.str());
}

}  // namespace

int runEval(const EvalCommandOptions& options) {
  discovery::EvalConfig eval;
  eval.splits = options.splits;
  eval.seed = options.seed;
  eval.ablation = options.ablation;
  eval.validate();
  const std::vector<std::unique_ptr<Category>> categories = parseCategories(options.categories);
  // The model is read before the output folder is made: a bad file leaves none behind.
  std::optional<discovery::ObjectnessModel> model;
  if (!options.model.empty()) model = discovery::ObjectnessModel::load(options.model);
  const OutputFolderLock lock = prepareOutputFolder(options.out);
  const SceneDiscovery set =
      labelledScenes(options.scenes, options.config, options.catalog, options.reading, model);
  const LabelledSegments segs = discovery::labelledSegments(set, options.config.max_iou);
  writeFileAtomically(options.out / "segments.csv", segmentsCsv(set, segs));

  nlohmann::json summary;
  summary["scenes"] = set.scenes.size();
  summary["segments"] = segs.measures.size();
  summary["splits"] = eval.splits;
  summary["seed"] = eval.seed;
  summary["segmentation"] = options.config.supports.enabled ? "support surfaces cut" : "paper";
  summary["ranking"] = model ? options.model.string() : std::string("average");
  std::printf("scenes        %zu, %zu segments after suppression\n", set.scenes.size(),
              segs.measures.size());
  std::printf(
      "ranked by     %s\n",
      model ? (toString(model->kind()) + std::string(" (") + options.model.string() + ")").c_str()
            : "average of the z-normalised measures");
  if (options.classifiers) {
    for (double iou : kLabelIous) evaluateAtIou(options, eval, segs, iou, summary);
  }
  writeRecall(options.out, recallTable(set, segs), summary);
  writeSceneFigures(options.out, set, categories, summary);
  writeFileAtomically(options.out / "hypotheses.csv", hypothesesCsv(set));
  writeFileAtomically(options.out / "summary.json",
                      summary.dump(1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
  report::Settings settings = options.settings;
  settings.catalog = report::catalogUseOf(set);
  report::writeSettings(options.out / report::kSettingsFile, settings);
  std::printf(
      "written       %s (ap.csv, pr_curves.csv/png, *_iou5/8, segments.csv, recall.csv, "
      "scenes.csv, hypotheses.csv, summary.json, settings.json)\n",
      options.out.c_str());
  return kExitSuccess;
}

namespace {

/// Below this many labelled segments of either class, train warns that its figures cannot be
/// trusted: each of the 5 folds then tests on fewer than 6 of that class, so one segment moves a
/// fold's AP by more than 0.15, and the grid search picks its parameters on those same folds, so
/// the cross-validated AP it reports flatters the model.
constexpr std::size_t kTrustedLabelsPerClass = 30;

/// Warns when the labels are too few to trust the model (kTrustedLabelsPerClass, one scene).
/// How many different values `v` holds.
std::size_t distinctCount(const std::vector<std::size_t>& v) {
  return std::set<std::size_t>(v.begin(), v.end()).size();
}

void warnIfTooFew(std::size_t objects, std::size_t not_objects, std::size_t scenes) {
  if (objects < kTrustedLabelsPerClass || not_objects < kTrustedLabelsPerClass) {
    log::warning("too few labels to trust this model: " + std::to_string(objects) +
                 " objects and " + std::to_string(not_objects) + " not objects, below " +
                 std::to_string(kTrustedLabelsPerClass) +
                 " of each (each cross-validation fold then tests on a handful, and the "
                 "parameters are chosen on the same folds, so the AP below flatters it): label "
                 "more, and compare it with the average score (discover without --model)");
  }
  if (scenes < 2) {
    log::warning(
        "all labels are from one scene: the cross-validated AP measures the model on the scene "
        "it was trained on, not on another; label segments of other scenes too");
  }
}

/// Leave-one-scene-out: what the model does on scenes it was not trained on, as discover uses it.
void printHeldOut(discovery::ScoreKind kind, const discovery::MeasureNormaliser& normaliser,
                  const std::vector<discovery::ShapeMeasures>& measures,
                  const std::vector<int>& labels, const std::vector<std::size_t>& scene_of,
                  const discovery::TrainConfig& config) {
  if (kind == discovery::ScoreKind::kAverage) return;
  std::vector<discovery::MeasureRow> rows;
  for (const discovery::ShapeMeasures& m : measures) rows.push_back(normaliser.normalise(m));
  const discovery::HeldOutScenes held = discovery::leaveOneSceneOut(
      kind, normaliser, rows, labels, scene_of, discovery::kAllMeasures, config);
  if (held.scenes == 0) {
    std::printf("held out      not measured: %s\n",
                held.skipped > 0 ? "no scene leaves enough labels of each class in the others"
                                 : "the labels are from one scene");
    return;
  }
  const std::string ap = std::isnan(held.ap) ? std::string("unknown (no object among them)")
                                              : std::to_string(held.ap).substr(0, 5);
  const std::string skipped =
      held.skipped == 0 ? std::string()
                        : ", " + std::to_string(held.skipped) +
                              " not held out (the others have too few of a class)";
  std::printf(
      "held out      AP %s, each of %zu scenes scored by a model trained on the others (%zu "
      "segments; scores %+.3f to %+.3f)%s\n",
      ap.c_str(), held.scenes, held.rows, held.min_score, held.max_score, skipped.c_str());
}

/// Fits `kind` to the measures and labels (normalised by `normaliser`) and writes the model file.
discovery::ObjectnessModel fitAndSave(const TrainCommandOptions& options, discovery::ScoreKind kind,
                                      const discovery::MeasureNormaliser& normaliser,
                                      const std::vector<discovery::ShapeMeasures>& measures,
                                      const std::vector<int>& labels,
                                      const discovery::TrainConfig& config) {
  std::vector<discovery::MeasureRow> rows;
  for (const discovery::ShapeMeasures& m : measures) rows.push_back(normaliser.normalise(m));
  discovery::ObjectnessModel model = discovery::ObjectnessModel::train(
      kind, normaliser, rows, labels, discovery::kAllMeasures, config);
  model.save(options.model);
  return model;
}

/// The parameters the grid search chose, and the file written.
void printChosen(const TrainCommandOptions& options, const discovery::ObjectnessModel& model) {
  if (!model.parameters().empty()) {
    std::printf("chosen        %s (5-fold cross-validated AP %.3f)\n", model.parameters().c_str(),
                model.crossValidatedAp());
  }
  std::printf("written       %s\n", options.model.c_str());
}

/// `objscan train --catalog C` without scenes: the labels people gave in objscan view.
int trainOnCatalogLabels(const TrainCommandOptions& options, discovery::ScoreKind kind) {
  if (!options.catalog) {
    throw std::invalid_argument(
        "objscan train needs labelled scenes, or --catalog C to train on the labels given in "
        "objscan view (run 'objscan train --help')");
  }
  const fs::path& catalog = *options.catalog;
  const discovery::CatalogTrainingSet set = discovery::catalogTrainingSet(catalog, options.config);
  const auto objects =
      static_cast<std::size_t>(std::count(set.labels.begin(), set.labels.end(), 1));
  const std::size_t not_objects = set.labels.size() - objects;
  discovery::TrainConfig config;
  config.seed = options.seed;
  const auto needed = static_cast<std::size_t>(config.folds);
  if (objects < needed || not_objects < needed) {
    throw std::invalid_argument(
        catalog.string() + ": too few labels to train on: " + std::to_string(objects) +
        " segments labelled object and " + std::to_string(not_objects) + " not an object (" +
        std::to_string(set.unsure) + " unsure and " + std::to_string(set.other_settings) +
        " of scenes measured with other settings left out); at least " + std::to_string(needed) +
        " of each are needed: label more in objscan view");
  }
  std::printf(
      "labels        %zu segments of %zu scenes in %s: %zu objects, %zu not objects; left out: "
      "%zu unsure, %zu of scenes measured with other settings\n",
      set.labels.size(), set.scenes, catalog.c_str(), objects, not_objects, set.unsure,
      set.other_settings);
  const discovery::ObjectnessModel model =
      fitAndSave(options, kind, set.normaliser, set.measures, set.labels, config);
  std::printf("trained       %s on %zu labelled segments\n", discovery::toString(kind),
              set.labels.size());
  printChosen(options, model);
  printHeldOut(kind, set.normaliser, set.measures, set.labels, set.scene_of, config);
  // The scenes the labels used come from, not every scene with a label (unsure ones add none).
  warnIfTooFew(objects, not_objects, distinctCount(set.scene_of));
  return kExitSuccess;
}

}  // namespace

int runTrain(const TrainCommandOptions& options) {
  const discovery::ScoreKind kind = discovery::scoreKindFromString(options.kind);
  if (options.scenes.empty()) return trainOnCatalogLabels(options, kind);
  const SceneDiscovery set =
      labelledScenes(options.scenes, options.config, options.catalog, options.reading);
  const LabelledSegments segs = discovery::labelledSegments(set, options.config.max_iou);
  const std::vector<int> labels = segs.labels(options.min_iou);
  discovery::TrainConfig config;
  config.seed = options.seed;
  const discovery::ObjectnessModel model =
      fitAndSave(options, kind, set.normaliser, segs.measures, labels, config);
  const auto objects = static_cast<std::size_t>(std::count(labels.begin(), labels.end(), 1));
  std::printf("trained       %s on %zu segments of %zu scenes (%zu objects at IoU >= %.1f)\n",
              discovery::toString(kind), labels.size(), set.scenes.size(), objects,
              options.min_iou);
  printChosen(options, model);
  printHeldOut(kind, set.normaliser, segs.measures, labels, segs.scene, config);
  warnIfTooFew(objects, labels.size() - objects, distinctCount(segs.scene));
  return kExitSuccess;
}

}  // namespace objscan::app
