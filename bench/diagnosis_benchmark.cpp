// Model-form diagnosis (diagnose(), diagnosis.hpp) measured on generated cases nobody tuned to:
// for each case number and problem a seeded generator draws a category and its parameters,
// builds a truth model holding the drawn effects, synthesizes noisy measured modes from it and
// runs the diagnosis with the library's defaults, then scores what it found against the truth.
//
// Categories (drawn per case with the weights in kCategoryWeights):
// - control: no effect, fresh noise;
// - single: one effect of a candidate family, drawn among generate_candidates() of the nominal
//   model: block stiffness or mass scale, joint/spring component, support flexibility, sensor
//   mass, spring between parts, spring or mass on a free node set, point mass or spring at a
//   surface node (the spatial family), stiffness or mass scale of a block's region (a cube of the
//   candidate grid), Poisson's ratio of an (E, nu) block (nu0 +/- u within [0.05, 0.45]); each
//   family the model has is equally likely;
// - outside list: a point mass or a spring to ground at a node drawn among *all* free nodes of
//   the blocks (interior ones included; the JSON says whether the node happens to be a spatial
//   candidate), or a stiffer/softer part of a block that is no candidate region: the elements whose centroid lies within a drawn
//   radius of a drawn node of the block (a ball, not a cube of the candidates' grid), which the
//   benchmark moves into a new block with its own stiffness_scale (same material properties);
// - multi: two or three effects at once, each drawn as for single or outside list;
// - below noise: one effect sized to shift a frequency by 0.01-0.1 % (the noise is 0.2 %);
// - finer mesh: the truth on a mesh refined 1.5x or 2x the problem's (LoadOptions refinement,
//   the path of `synth --refine`; the sensors are found in the truth model by position, as the
//   data-file loader does), without an effect (a control of discretization) or with one.
//
// Effect size: a target largest noise-free frequency shift is drawn log-uniform in
// [--min-shift, --max-shift] (below noise: [0.01 %, 0.1 %]); the change value is then set by a
// secant iteration in log(amount) vs log(shift) on noise-free forward solves of the truth (at most
// 6 solves, stopping within 10 % of the target; an effect whose shift saturates below the target,
// e.g. a spring that pins its node, keeps its largest value). "Amount" u maps to the value as
// nominal*(1+u) or nominal/(1+u) (scale factors, present stiffnesses), u*reference (absent
// components, added masses and springs, reference from make_candidate()), reference/u (a support's
// stiffness) or nu0 +/- u (Poisson's ratio).
//
// Detectability, decided from the data before the diagnosis runs: lambda, the noncentrality of
// the noise-weighted chi-square that the calibration cannot absorb, is |(I - J J^+) r|^2 with r the
// noise-weighted residual of the nominal model at the true parameter values against noise-free
// data of the truth and J its Jacobian in the calibration parameters (first order: what the
// calibration absorbs). An effect is detectable when lambda >= lambda* = (sqrt(c) + 1.2816)^2, c
// the chi-square(1) critical value at alpha / N (N the number of candidates generated for the
// nominal model): a candidate carrying that lambda would pass the first step's Bonferroni
// likelihood-ratio test with 90 % probability. A multi-effect case is detectable when each of its
// effects alone is; a finer-mesh case with an effect when its effect alone (on the problem's
// mesh) is. A multi-effect case is also scored against a stricter reading, detectable given the
// others: each effect still carries lambda* once the others are in the model, their values and
// the parameters refitted to noise-free data of the whole truth (the chi-square left when the
// truth without that effect is calibrated to them). Two effects whose signatures nearly coincide
// (a mass and a spring at one node, two supports of one base) fail it, and so do effects the
// others take in at other values (the largest of three masses, 10 % lighter, for all three): no
// rule could find all of them from these data, however it searched. Where an effect is no
// candidate (a part of a block), the reading is first order: each effect's own signature (its
// residual alone), once the calibration's Jacobian and the other effects' signatures absorb what
// they can.
//
// Scores per case: flagged (the verdict, Diagnosis::model_form_error); the first accepted effect
// kept by the backward pass has the right kind and place (the rules in kinds_match(): the same
// candidate for joint, support and node-set truths, the right block's stiffness_scale or
// mass_scale for block-wide truths, the block's nu for Poisson truths, the block's
// stiffness_scale or a local stiffness effect in the part for part-of-block truths, mass added at
// a place (a point mass or a heavier region: one kind in the library's prior) or a spring to
// ground in the same direction within two element sizes for node truths and heavier-region
// truths); every truth effect matched by some kept effect; final residual p-value; relative error of the accepted value's change from nominal
// against the truth's (compliance for supports; not for Poisson or part-of-block truths);
// wall and CPU seconds. The single effects are also tallied by signal strength, lambda / lambda*:
// finding the place takes more signal than flagging the effect does. "The place as stated": the
// first kept effect has the right kind, the truth within its stated place spread
// (DiagnosisStep::place_spread) plus two element sizes.
//
// What the data could tell (an oracle, for truths on the problem's own mesh): the truth model
// itself, calibrated from the true parameter values, gives a chi-square; a miss whose data
// favour the truth model over the diagnosis's final model by 20 : 1 or more (and, for each
// effect the truth has more than was accepted, by the loop's critical value more) is one a
// better rule could have avoided; the others are misses the data cannot tell from a right answer.
// The data's ceiling per target: the detectable cases less those other misses, the most that any
// rule answering by the data could score on the cases drawn.
//
// Usage: diagnosis_benchmark [--problem PATH]... [--cases N[,N..]] [--controls M[,M..]]
//          [--seed-base B] [--json FILE] [--significance A] [--dry-run] [--only CATEGORY]
//          [--case-list K,..]   (--help for all)
// Tuning runs use --seed-base 1000, reporting runs 2000 (docs/benchmarks.md).

#include <sys/resource.h>

#include <Eigen/QR>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "modalcal/block_geometry.hpp"
#include "modalcal/diagnosis.hpp"
#include "modalcal/effects.hpp"
#include "modalcal/elements.hpp"
#include "modalcal/model_change.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/residual_test.hpp"
#include "modalcal/synthesis.hpp"
#include "modalcal/problem_file.hpp"
#include "modalcal/reduced.hpp"
#include "support/random_draws.hpp"

using namespace modalcal;
using modalcal::bench::seconds_since;
using Clock = modalcal::bench::Clock;
using json = nlohmann::json;

namespace {

double cpu_seconds() {
  struct rusage usage;
  getrusage(RUSAGE_SELF, &usage);
  auto seconds = [](const timeval& t) { return t.tv_sec + 1e-6 * t.tv_usec; };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

std::string run_command(const std::string& command) {
  std::string out;
  if (FILE* pipe = popen(command.c_str(), "r")) {
    char buffer[256];
    while (std::fgets(buffer, sizeof buffer, pipe)) out += buffer;
    pclose(pipe);
  }
  while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
  return out;
}

std::string format(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

std::string point_text(const Vec3& x) {
  return "[" + format_round_trip(x[0]) + "," + format_round_trip(x[1]) + "," + format_round_trip(x[2]) + "]";
}

// ---------------------------------------------------------------------------------------------
// Categories and families

enum class Category { Control, Single, Outside, Multi, BelowNoise, FineControl, FineEffect };
const char* category_name(Category c) {
  switch (c) {
    case Category::Control: return "control";
    case Category::Single: return "single (candidate family)";
    case Category::Outside: return "single (outside the list)";
    case Category::Multi: return "two or three effects";
    case Category::BelowNoise: return "below the noise";
    case Category::FineControl: return "finer mesh, no effect";
    case Category::FineEffect: return "finer mesh, one effect";
  }
  return "?";
}
const char* category_key(Category c) {
  switch (c) {
    case Category::Control: return "control";
    case Category::Single: return "single";
    case Category::Outside: return "outside";
    case Category::Multi: return "multi";
    case Category::BelowNoise: return "below-noise";
    case Category::FineControl: return "fine-control";
    case Category::FineEffect: return "fine-effect";
  }
  return "?";
}
const std::vector<std::pair<Category, double>> kCategoryWeights = {
    {Category::Control, 0.14}, {Category::Single, 0.26},     {Category::Outside, 0.20},     {Category::Multi, 0.12},
    {Category::BelowNoise, 0.12}, {Category::FineControl, 0.08}, {Category::FineEffect, 0.08}};

enum class Family {
  BlockStiffness, BlockMass, JointComponent, Support, SensorMass, BetweenParts, NodeSet, SurfaceNode,
  RegionScale, AnyNodeMass, AnyNodeSpring, PartialBlock, Poisson
};
const char* family_name(Family f) {
  switch (f) {
    case Family::BlockStiffness: return "block stiffness scale";
    case Family::BlockMass: return "block mass scale";
    case Family::JointComponent: return "joint/spring component";
    case Family::Support: return "support flexibility";
    case Family::SensorMass: return "sensor mass";
    case Family::BetweenParts: return "spring between parts";
    case Family::NodeSet: return "node-set spring/mass";
    case Family::SurfaceNode: return "surface-node mass/spring";
    case Family::RegionScale: return "block region stiffness/mass";
    case Family::AnyNodeMass: return "point mass, any node";
    case Family::AnyNodeSpring: return "spring to ground, any node";
    case Family::PartialBlock: return "stiffness of part of a block";
    case Family::Poisson: return "Poisson's ratio of a block";
  }
  return "?";
}
bool outside_list(Family f) {
  return f == Family::AnyNodeMass || f == Family::AnyNodeSpring || f == Family::PartialBlock;
}

// ---------------------------------------------------------------------------------------------
// A drawn effect

enum class Map { ScaleUp, ScaleDown, FromZero, Compliance, PlusU, MinusU };

struct EffectSpec {
  Family family = Family::BlockStiffness;
  ModelChange change;          // value set from the amount (unused for PartialBlock)
  std::string name;            // canonical name on the problem's mesh ("partial:<block>" for a part)
  std::string block;           // block-wide, Poisson, part-of-block and region truths
  std::optional<Vec3> location;  // where it acts on the problem's mesh (none: block-wide)
  Vec3 region_center = Vec3::Zero();
  double region_radius = 0;
  int region_elements = 0, block_elements = 0;
  bool in_list = true;         // a candidate of generate_candidates() for the nominal model
  Map map = Map::ScaleUp;
  double nominal = 0, reference = 1, u_min = 1e-12, u_max = 1;
  double u = 0, value = 0;
  double target_shift = 0, shift = 0;  // largest noise-free frequency shift alone (relative)
  int sizing_solves = 0;
  double lambda = NAN;         // noncentrality alone
  double lambda_given_others = NAN;  // noncentrality once the case's other effects absorb theirs
  double lambda_given_others_refit = NAN;  // the same, refitted (noncentrality_given_others_refit())

  double value_of(double amount) const {
    switch (map) {
      case Map::ScaleUp: return nominal * (1 + amount);
      case Map::ScaleDown: return nominal / (1 + amount);
      case Map::FromZero: return amount * reference;
      case Map::Compliance: return reference / amount;
      case Map::PlusU: return nominal + amount;
      case Map::MinusU: return nominal - amount;
    }
    return NAN;
  }
  std::string text() const {
    if (family == Family::PartialBlock)
      return "part of block " + block + " (" + std::to_string(region_elements) + " of " + std::to_string(block_elements) +
             " elements, centroids within " + format("%.3g", region_radius) + " of " + point_text(region_center) +
             "): stiffness x" + format("%.4g", value);
    ModelChange c = change;
    c.value = value;
    return to_string(c);
  }
};

// ---------------------------------------------------------------------------------------------
// Per problem: the nominal set-up, its candidates and scales

struct ProblemContext {
  std::string path;
  Problem problem;  // nominal, noise stated, measured = noise-free truth-parameter modes
  MeasurementNoise noise;
  double refinement = 1;
  std::vector<double> fine_ratios;  // refinements (times the problem's) whose meshes hold every sensor position
  std::map<double, Problem> fine;
  std::optional<Problem> check;  // the finer mesh of the diagnosis's discretization estimate
  SynthesisOptions synthesis;
  std::vector<double> base_hz;
  Vector truth;
  std::vector<EffectCandidate> candidates;
  std::map<Family, std::vector<int>> family_candidates;  // indices into candidates
  std::set<int> spatial_nodes;
  std::vector<double> block_h;                 // per block: cbrt(mean element volume), as the library
  std::vector<std::vector<int>> blocks_of_node;
  std::vector<int> free_nodes;                 // in a block, not fixed along all of x, y, z
  std::vector<std::array<bool, 6>> fixed;
  double lambda_star = 0, critical = 0;
};

/// The refinement a problem file sets for its generated mesh: the first `refinement:` line of the
/// file or of the files it extends (1 when none).
double file_refinement(const std::string& path) {
  std::ifstream in(path);
  std::string line, extends;
  while (std::getline(in, line)) {
    const size_t at = line.find("refinement:");
    if (at != std::string::npos && line.find_first_not_of(" \t") == at) return std::stod(line.substr(at + 11));
    if (line.rfind("extends:", 0) == 0) {
      extends = line.substr(8);
      extends.erase(0, extends.find_first_not_of(" \t"));
      extends = extends.substr(0, extends.find_first_of(" \t#"));
    }
  }
  if (extends.empty()) return 1;
  const size_t slash = path.rfind('/');
  return file_refinement(slash == std::string::npos ? extends : path.substr(0, slash + 1) + extends);
}

double element_size_at(const ProblemContext& ctx, const Vec3& x) {
  int best = -1;
  double distance = INFINITY;
  for (int v = 0; v < ctx.problem.model.num_nodes(); ++v)
    if (!ctx.blocks_of_node[v].empty())
      if (const double d = (ctx.problem.model.coordinates[v] - x).norm(); d < distance) {
        distance = d;
        best = v;
      }
  double h = 0;
  if (best >= 0)
    for (int b : ctx.blocks_of_node[best]) h = std::max(h, ctx.block_h[b]);
  return h;
}

MeasuredData synthesize(const ProblemContext& ctx, const TruthModel& truth, const MeasurementNoise& noise, bool shapes,
                        const Problem* mesh = nullptr) {
  SynthesisOptions options = ctx.synthesis;
  options.noise = noise;
  options.shapes = shapes && options.shapes;
  // On a finer mesh the truth is measured at that mesh's own sensor nodes (the problem file's
  // sensor points snapped to its nodes, in the same order), as `synth --refine` does.
  if (mesh && mesh != &ctx.problem) return synthesize_measured_data(*mesh, truth, mesh->sensors, options);
  return synthesize_measured_data(ctx.problem, truth, ctx.problem.sensors, options);
}

/// Writes a case's data (`case-SEED-data.yaml`) and a problem that reads them on the nominal
/// problem at `nominal_path` (`case-SEED.yaml`) into `folder`, so that `fullspace_calib diagnose`
/// (any version that reads the format) can run the case as a user would. Refuses to replace a
/// file there: the folder is the caller's.
void write_case(const std::string& folder, const std::string& nominal_path, std::uint64_t seed,
                const MeasuredData& data) {
  namespace fs = std::filesystem;
  fs::create_directories(folder);
  const std::string stem = "case-" + std::to_string(seed);
  const fs::path data_path = fs::path(folder) / (stem + "-data.yaml"), problem_path = fs::path(folder) / (stem + ".yaml");
  for (const fs::path& out : {data_path, problem_path})
    if (fs::exists(out)) throw std::invalid_argument("--write-data: " + out.string() + " exists; not replaced");
  write_measured_data(data_path.string(), data, {nominal_path});
  std::ofstream problem(problem_path);
  problem << "# Case " << seed << " of diagnosis_benchmark; `fullspace_calib diagnose " << problem_path.filename().string()
          << "` runs it.\n"
          << "extends: " << fs::absolute(nominal_path).string() << "\n"
          << "name: " << stem << "\n"
          << "measured: {file: " << data_path.filename().string() << "}\n";
  problem.close();  // a failed write shows only once the buffer is flushed
  if (!problem) throw std::runtime_error("--write-data: cannot write " + problem_path.string());
}

/// The noise-weighted chi-square of `problem` calibrated (reduced L-BFGS) from `p0`; NaN when it
/// cannot be evaluated.
double calibrated_chi2(const Problem& problem, const Vector& p0, const MeasurementNoise& noise) {
  const Problem weighted = noise_weighted(problem, noise);
  Objective objective(weighted);
  const ReducedSummary fit = minimize_reduced(objective, p0, ReducedOptions());
  const Evaluation e = objective.evaluate(fit.final.size() == p0.size() ? fit.final : p0);
  if (!e.ok) return NAN;
  return test_residual(objective, e, noise, static_cast<int>(p0.size())).statistic;
}

/// The chi-square of the truth model itself (its effects at their true values), calibrated from
/// the true parameter values against the case's data: about what the right effect's refit can
/// reach, an oracle no diagnosis has. Below the diagnosis's final chi-square, the data favour the
/// truth over what was accepted; above it, they favour the accepted effect, and no rule that
/// reads the data could have named the truth.
double truth_model_chi2(const Problem& problem, const TruthModel& truth, const MeasuredData& data) {
  Problem p = problem;  // the calibration parameters, the case's data
  p.model = truth.problem.model;
  Vector p0(static_cast<Eigen::Index>(p.parameters.size()));
  for (size_t i = 0; i < p.parameters.size(); ++i)
    p0[static_cast<Eigen::Index>(i)] = p.parameters[i].truth.value_or(p.parameters[i].initial);
  return calibrated_chi2(p, p0, *data.noise);
}

/// Moves the elements of `block` whose centroid lies within `radius` of `center` into a new block
/// with its own stiffness multiplier `scale` (times the block's). Returns the number moved.
int scale_part_of_block(Model* model, const std::string& block, const Vec3& center, double radius, double scale,
                        int* total) {
  auto it = std::find_if(model->blocks.begin(), model->blocks.end(), [&](const ElementBlock& b) { return b.name == block; });
  if (it == model->blocks.end()) throw std::invalid_argument("no block " + block);
  ElementBlock& b = *it;
  const int npe = nodes_per_element(b.type);
  const std::vector<Vec3> centroids = element_centroids(*model, b);
  std::vector<int> inside, outside;
  for (int e = 0; e < b.num_elements(); ++e) {
    std::vector<int>& to = (centroids[e] - center).norm() <= radius ? inside : outside;
    to.insert(to.end(), b.connectivity.begin() + e * npe, b.connectivity.begin() + (e + 1) * npe);
  }
  *total = b.num_elements();
  if (inside.empty() || outside.empty()) return static_cast<int>(inside.size()) / npe;
  ElementBlock part = b;
  part.name = b.name + "_part";
  part.connectivity = inside;
  const double base = b.stiffness_scale == kNoProperty ? 1 : model->property_value(b.stiffness_scale);
  b.connectivity = outside;
  part.stiffness_scale = model->add_property(part.name + ".stiffness_scale", base * scale);
  model->blocks.push_back(part);
  return static_cast<int>(inside.size()) / npe;
}

/// A change placed by node id, placed by the node's position instead (for a truth on another mesh).
ModelChange placed_by_point(const Model& model, ModelChange change) {
  for (NodePlace& p : change.places)
    if (p.kind == NodePlace::Kind::NodeId) {
      p.point = model.coordinates[model.find_node(p.node_id)];
      p.kind = NodePlace::Kind::Point;
    }
  return change;
}

/// The truth: the problem's model at the parameters' truth values with `effects` at their values,
/// on `mesh` (the problem itself or a refined load of it).
TruthModel build_truth(const ProblemContext& ctx, const Problem& mesh, const std::vector<EffectSpec>& effects) {
  const bool other_mesh = &mesh != &ctx.problem;
  std::vector<ModelChange> changes;
  for (const EffectSpec& e : effects) {
    if (e.family == Family::PartialBlock) continue;
    ModelChange c = other_mesh ? placed_by_point(ctx.problem.model, e.change) : e.change;
    c.value = e.value;
    changes.push_back(c);
  }
  TruthModel truth = make_truth(mesh, nullptr, changes);
  for (const EffectSpec& e : effects)
    if (e.family == Family::PartialBlock) {
      int total = 0;
      const int moved = scale_part_of_block(&truth.problem.model, e.block, e.region_center, e.region_radius, e.value, &total);
      if (moved == 0 || moved == total) throw std::runtime_error("part of block " + e.block + " is empty or all of it");
      truth.record.changes.push_back(e.text());
    }
  return truth;
}

double largest_shift(const ProblemContext& ctx, const MeasuredData& data) {
  double s = 0;
  for (size_t i = 0; i < data.truth_modes.size(); ++i)
    s = std::max(s, std::abs(data.truth_modes[i].frequency_hz / ctx.base_hz[i] - 1));
  return s;
}

/// What noise-free measured data `data` of a truth look like to the nominal model at the true
/// parameter values: the noise-weighted residual and the Jacobian in the calibration parameters,
/// its columns scaled to unit length. Empty when the model cannot be evaluated.
struct Signature {
  Vector residual;
  Matrix jacobian;
};

Signature signature(const ProblemContext& ctx, const MeasuredData& data) {
  Problem p = ctx.problem;
  p.measured = data.modes;
  p.synthetic.reset();
  p.measurement_noise = ctx.noise;
  const Problem weighted = noise_weighted(p, ctx.noise);
  Objective objective(weighted);
  const Evaluation e = objective.evaluate(ctx.truth, Need::Jacobian);
  if (!e.ok) return {};
  Signature s{e.residuals, e.jacobian};
  for (Eigen::Index j = 0; j < s.jacobian.cols(); ++j)
    if (const double n = s.jacobian.col(j).norm(); n > 0) s.jacobian.col(j) /= n;
  return s;
}

/// |(I - A A^+) r|^2: what of r the columns of A cannot absorb.
double unabsorbed(const Matrix& A, const Vector& r) {
  const Eigen::ColPivHouseholderQR<Matrix> qr(A);
  const Matrix Q = qr.householderQ() * Matrix::Identity(A.rows(), qr.rank());
  return (r - Q * (Q.transpose() * r)).squaredNorm();
}

/// Noncentrality of the chi-square the calibration cannot absorb (first order), for a truth's
/// signature `s`.
double noncentrality(const Signature& s) { return s.residual.size() ? unabsorbed(s.jacobian, s.residual) : NAN; }

/// For each effect of a multi-effect truth, the noncentrality its own signature keeps once the
/// calibration and the other effects' signatures (each alone, first order) absorb what they can:
/// what the data could tell of it if every other effect were known to be there.
std::vector<double> noncentrality_given_others(const std::vector<Signature>& alone) {
  std::vector<double> out(alone.size(), NAN);
  for (size_t i = 0; i < alone.size(); ++i) {
    const Signature& s = alone[i];
    if (s.residual.size() == 0) continue;
    Matrix A = s.jacobian;
    bool same_shape = true;
    for (size_t j = 0; j < alone.size(); ++j) {
      if (j == i) continue;
      const Vector& r = alone[j].residual;
      if (r.size() != s.residual.size()) {
        same_shape = false;
        break;
      }
      A.conservativeResize(Eigen::NoChange, A.cols() + 1);
      A.col(A.cols() - 1) = r.norm() > 0 ? Vector(r / r.norm()) : r;
    }
    if (same_shape) out[i] = unabsorbed(A, s.residual);
  }
  return out;
}

/// For each effect of a multi-effect truth on the problem's mesh, the chi-square that noise-free
/// data of the whole truth (`noise_free`) keep once the truth without that effect is calibrated to
/// them: the parameters and the other effects' values free, from their true values. The
/// noncentrality of the likelihood-ratio test for that effect at a step where the others are in
/// the model, with what the others absorb at any value, not only to first order (three masses on
/// two columns: the largest, refitted 10 % lighter, takes in the other two). NaN for every effect
/// when one is no candidate (a part of a block) or a calibration cannot be evaluated.
std::vector<double> noncentrality_given_others_refit(const ProblemContext& ctx, const std::vector<EffectSpec>& effects,
                                                     const MeasuredData& noise_free) {
  std::vector<double> out(effects.size(), NAN);
  try {
    std::vector<EffectCandidate> all;
    for (const EffectSpec& e : effects) {  // the screened candidate, or one made for a node outside the list
      const auto it = std::find_if(ctx.candidates.begin(), ctx.candidates.end(),
                                   [&](const EffectCandidate& c) { return c.name == e.name; });
      all.push_back(it != ctx.candidates.end() ? *it : make_candidate(ctx.problem, e.text()));
    }
    for (size_t k = 0; k < effects.size(); ++k) {
      std::vector<EffectCandidate> others;
      std::vector<double> values;
      for (size_t j = 0; j < effects.size(); ++j)
        if (j != k) {
          others.push_back(all[j]);
          values.push_back(effects[j].value);
        }
      Problem p = problem_with_effects(ctx.problem, others, values);
      p.measured = noise_free.modes;
      p.synthetic.reset();
      Vector p0(static_cast<Eigen::Index>(p.parameters.size()));
      p0 << ctx.truth, Eigen::Map<const Vector>(values.data(), static_cast<Eigen::Index>(values.size()));
      out[k] = calibrated_chi2(p, p0, ctx.noise);
      if (!std::isfinite(out[k])) return std::vector<double>(effects.size(), NAN);
    }
  } catch (const std::invalid_argument&) {  // a part of a block: no candidate
    return std::vector<double>(effects.size(), NAN);
  }
  return out;
}

/// Sets e->u and e->value so that the largest noise-free frequency shift of the truth with `e`
/// alone is about e->target_shift (secant in log-log, at most 6 solves).
void size_effect(const ProblemContext& ctx, EffectSpec* e) {
  auto shift_at = [&](double u) {
    EffectSpec trial = *e;
    trial.u = u;
    trial.value = trial.value_of(u);
    ++e->sizing_solves;
    const double s = largest_shift(ctx, synthesize(ctx, build_truth(ctx, ctx.problem, {trial}), MeasurementNoise{}, false));
    if (std::getenv("DIAGNOSIS_BENCHMARK_TRACE")) std::fprintf(stderr, "  size %s: u %.4g value %.4g shift %.4g (target %.4g)\n", trial.name.c_str(), u, trial.value, s, e->target_shift);
    return s;
  };
  double u = std::clamp(e->map == Map::FromZero ? 1.0 : e->map == Map::Compliance ? 0.01 : e->map == Map::PlusU || e->map == Map::MinusU ? 0.02 : 0.1,
                        e->u_min, e->u_max);
  double s = shift_at(u);
  // Secant steps in log(shift) against log(u), kept inside the bracket [lo, hi] (shift below,
  // above the target) once there is one, else bisection in log(u).
  double lo = NAN, hi = NAN, u_prev = NAN, s_prev = NAN, slope = 1;
  for (int k = 0; k < 7; ++k) {
    if (s > 0 && std::abs(s / e->target_shift - 1) < 0.1) break;
    (s < e->target_shift ? lo : hi) = u;
    double next;
    if (!(s > 0)) {
      next = u * 100;
    } else {
      if (std::isfinite(u_prev) && s_prev > 0 && u != u_prev && s != s_prev)
        slope = std::clamp(std::log(s / s_prev) / std::log(u / u_prev), 0.1, 3.0);
      next = u * std::pow(e->target_shift / s, 1 / slope);
    }
    if (std::isfinite(lo) && std::isfinite(hi) && !(next > std::min(lo, hi) && next < std::max(lo, hi)))
      next = std::sqrt(lo * hi);
    next = std::clamp(next, e->u_min, e->u_max);
    if (next == u) break;  // saturated at a bound
    u_prev = u;
    s_prev = s;
    u = next;
    s = shift_at(u);
  }
  e->u = u;
  e->value = e->value_of(u);
  e->shift = s;
}

// ---------------------------------------------------------------------------------------------
// Drawing cases

struct Case {
  int number = 0;
  std::uint64_t seed = 0, noise_seed = 0;
  Category category = Category::Control;
  std::vector<EffectSpec> effects;
  double fine_ratio = 0;  // 0: the problem's mesh
  double lambda_case = NAN;
  bool detectable = false;
  // A multi-effect case each of whose effects stays detectable when the others are known to be
  // there (noncentrality_given_others()); for a single effect, the same as `detectable`.
  bool detectable_given_others = false;
  std::string error;
};

/// A candidate's family, from its change.
std::optional<Family> family_of(const EffectCandidate& c) {
  const ModelChange& ch = c.change;
  const bool node_place = !ch.places.empty() && ch.places[0].kind == NodePlace::Kind::NodeId;
  switch (ch.kind) {
    case ModelChange::Kind::SetProperty:
      if (ch.property == "stiffness_scale") return Family::BlockStiffness;
      if (ch.property == "mass_scale") return Family::BlockMass;
      if (ch.property == "nu") return Family::Poisson;
      return Family::JointComponent;
    case ModelChange::Kind::FlexibleSupport: return Family::Support;
    case ModelChange::Kind::AddJoint: return Family::BetweenParts;
    case ModelChange::Kind::AddRegion: return Family::RegionScale;
    case ModelChange::Kind::AddPointMass:
    case ModelChange::Kind::AddSpring:
      if (!node_place) return Family::NodeSet;
      if (c.description.find("sensor") != std::string::npos) return Family::SensorMass;
      return Family::SurfaceNode;
  }
  return std::nullopt;
}

ProblemContext make_context(const std::string& path, const MeasurementNoise& noise) {
  ProblemContext ctx;
  ctx.path = path;
  ctx.problem = load_problem(path);
  synthesize_measured(&ctx.problem);
  ctx.noise = noise;
  ctx.refinement = file_refinement(path);
  if (!ctx.problem.synthetic) throw std::invalid_argument(path + ": needs measured: synthetic (the truth modes to measure)");
  ctx.synthesis.modes = ctx.problem.synthetic->modes;
  ctx.synthesis.shapes = ctx.problem.synthetic->shapes && !ctx.problem.sensors.empty();
  ctx.truth = ctx.problem.truth_values();
  ctx.problem.measurement_noise = noise;
  const MeasuredData base = synthesize(ctx, make_truth(ctx.problem, nullptr, {}), MeasurementNoise{}, false);
  for (const TruthModeRecord& t : base.truth_modes) ctx.base_hz.push_back(t.frequency_hz);

  const Model& model = ctx.problem.model;
  ctx.fixed.assign(model.num_nodes(), {false, false, false, false, false, false});
  for (const FixedDofs& f : model.fixed)
    for (int v : f.nodes)
      for (int c = 0; c < 6; ++c) ctx.fixed[v][c] = ctx.fixed[v][c] || f.components[c];
  const BlockGeometry geometry = block_geometry(model);
  ctx.blocks_of_node = geometry.blocks_of_node;
  for (size_t b = 0; b < model.blocks.size(); ++b) ctx.block_h.push_back(geometry.element_size(model, static_cast<int>(b)));
  for (int v = 0; v < model.num_nodes(); ++v)
    if (!ctx.blocks_of_node[v].empty() && !(ctx.fixed[v][0] && ctx.fixed[v][1] && ctx.fixed[v][2])) ctx.free_nodes.push_back(v);

  // The cases are drawn from one fixed list, whatever the diagnosis screens (--region-levels,
  // --no-region-stagger), so that a seed draws the same case under every option: the regions of
  // the finest grid only, unshifted.
  CandidateOptions drawn_from;
  drawn_from.region_levels = 1;
  drawn_from.region_stagger = false;
  ctx.candidates = generate_candidates(noise_weighted(ctx.problem, noise), drawn_from);
  for (size_t k = 0; k < ctx.candidates.size(); ++k) {
    const EffectCandidate& c = ctx.candidates[k];
    if (c.change.kind == ModelChange::Kind::SetProperty && c.change.property != "stiffness_scale" &&
        c.change.property != "mass_scale" && c.change.property.rfind("k", 0) != 0)
      continue;  // point-mass inertia and the like: not drawn
    if (const std::optional<Family> f = family_of(c)) ctx.family_candidates[*f].push_back(static_cast<int>(k));
    if (family_of(c) == Family::SurfaceNode || family_of(c) == Family::SensorMass)
      ctx.spatial_nodes.insert(model.find_node(c.change.places[0].node_id));
  }
  return ctx;
}

/// The problem loaded on finer meshes; a ratio is usable when its sensors are the problem's (same
/// count, directions and order); prints how far they moved.
void find_fine_ratios(ProblemContext* ctx, const std::vector<double>& ratios) {
  for (double r : ratios) {
    try {
      Problem fine = load_problem(ctx->path, LoadOptions{r * ctx->refinement});
      synthesize_measured(&fine);
      if (fine.sensors.size() != ctx->problem.sensors.size()) throw std::runtime_error("another number of sensors");
      double offset = 0;
      for (size_t s = 0; s < fine.sensors.size(); ++s) {
        if (fine.sensors[s].component != ctx->problem.sensors[s].component) throw std::runtime_error("sensor directions differ");
        offset = std::max(offset, (fine.model.coordinates[fine.sensors[s].node] -
                                   ctx->problem.model.coordinates[ctx->problem.sensors[s].node]).norm());
      }
      std::printf("# truth mesh x%g (refinement %g): %d nodes, sensors moved by up to %.3g\n", r, r * ctx->refinement,
                  fine.model.num_nodes(), offset);
      ctx->fine.emplace(r, std::move(fine));
      ctx->fine_ratios.push_back(r);
    } catch (const std::exception& e) {
      std::printf("# truth mesh x%g of %s not usable: %s\n", r, ctx->path.c_str(), e.what());
    }
  }
}

struct Drawer {
  detail::Uniform& u;
  int index(int n) { return std::min(n - 1, static_cast<int>(u(0, n))); }
  double log_uniform(double lo, double hi) { return std::exp(u(std::log(lo), std::log(hi))); }
  bool coin() { return u(0, 1) < 0.5; }
};

/// One effect of `family` with target shift `target`; nullopt when the model offers none.
std::optional<EffectSpec> draw_effect(const ProblemContext& ctx, Family family, double target, Drawer& draw) {
  const Model& model = ctx.problem.model;
  EffectSpec e;
  e.family = family;
  e.target_shift = target;
  auto from_candidate = [&](const EffectCandidate& c) {
    e.change = c.change;
    e.name = c.name;
    e.location = c.location;
    e.reference = c.reference;
    if (c.change.kind == ModelChange::Kind::SetProperty && (c.change.property == "stiffness_scale" || c.change.property == "mass_scale"))
      e.block = c.change.entity;
    // A region's block too: another effect on that block (a part of it moved into a block of its
    // own, or a second region) would clash with it in the truth model.
    if (c.change.kind == ModelChange::Kind::AddRegion && !c.change.places.empty()) e.block = c.change.places[0].node_set;
    switch (c.variable) {
      case EffectCandidate::Variable::Log:
        e.map = draw.coin() ? Map::ScaleUp : Map::ScaleDown;
        e.nominal = c.nominal;
        e.u_max = 9;
        break;
      case EffectCandidate::Variable::Linear:
        e.map = Map::FromZero;
        e.u_max = c.upper / c.reference;
        break;
      case EffectCandidate::Variable::Compliance:
        e.map = Map::Compliance;
        e.u_min = 1e-6;
        e.u_max = 1000;
        break;
    }
  };
  if (!outside_list(family) && family != Family::Poisson) {  // Poisson: drawn below, within physical bounds
    const auto it = ctx.family_candidates.find(family);
    if (it == ctx.family_candidates.end() || it->second.empty()) return std::nullopt;
    from_candidate(ctx.candidates[it->second[draw.index(static_cast<int>(it->second.size()))]]);
    return e;
  }
  if (family == Family::AnyNodeMass || family == Family::AnyNodeSpring) {
    const int v = ctx.free_nodes[draw.index(static_cast<int>(ctx.free_nodes.size()))];
    std::string text = "point_mass@#" + std::to_string(model.node_ids[v]) + ":mass";
    if (family == Family::AnyNodeSpring) {
      std::vector<int> free;
      for (int c = 0; c < 3; ++c)
        if (!ctx.fixed[v][c]) free.push_back(c);
      text = "spring@#" + std::to_string(model.node_ids[v]) + ":" + kStiffnessComponentNames[free[draw.index(static_cast<int>(free.size()))]];
    }
    from_candidate(make_candidate(ctx.problem, text));
    e.in_list = ctx.spatial_nodes.count(v) > 0;
    return e;
  }
  // Poisson's ratio or part of a block: a block drawn among those that have the property.
  std::vector<int> blocks;
  for (size_t b = 0; b < model.blocks.size(); ++b) {
    const ElementBlock& block = model.blocks[b];
    if (family == Family::Poisson) {
      if (block.form != ElasticForm::YoungPoisson) continue;
      const std::string name = model.properties[block.modulus_b].name;
      bool calibrated = false;
      for (const Parameter& q : ctx.problem.parameters)
        for (PropertyId t : q.targets) calibrated = calibrated || model.properties[t].name == name;
      if (calibrated) continue;
    }
    if (family == Family::PartialBlock && block.num_elements() < 8) continue;
    blocks.push_back(static_cast<int>(b));
  }
  if (blocks.empty()) return std::nullopt;
  const ElementBlock& block = model.blocks[blocks[draw.index(static_cast<int>(blocks.size()))]];
  e.block = block.name;
  e.in_list = family == Family::Poisson;  // the library screens every (E, nu) block's nu
  if (family == Family::Poisson) {
    e.change = parse_model_change(model.properties[block.modulus_b].name + "=0.3");
    e.name = model.properties[block.modulus_b].name;
    e.nominal = model.property_value(block.modulus_b);
    e.map = draw.coin() ? Map::PlusU : Map::MinusU;
    e.u_max = e.map == Map::PlusU ? 0.45 - e.nominal : e.nominal - 0.05;
    return e;
  }
  // Part of a block: the elements whose centroids lie within a radius of one of its nodes, the
  // radius taking a drawn share (5-30 %) of the block's elements, at least one, never all.
  const int v = block.connectivity[draw.index(static_cast<int>(block.connectivity.size()))];
  e.region_center = model.coordinates[v];
  std::vector<double> distances;
  for (const Vec3& c : element_centroids(model, block)) distances.push_back((c - e.region_center).norm());
  std::sort(distances.begin(), distances.end());
  const int n = static_cast<int>(distances.size());
  const int take = std::clamp(static_cast<int>(std::lround(draw.u(0.05, 0.30) * n)), 1, n - 1);
  e.region_radius = 0.5 * (distances[take - 1] + distances[take]);
  Model copy = model;
  e.region_elements = scale_part_of_block(&copy, block.name, e.region_center, e.region_radius, 1.0, &e.block_elements);
  if (e.region_elements == 0 || e.region_elements == e.block_elements) return std::nullopt;
  e.name = "partial:" + block.name;
  e.location = e.region_center;
  e.map = draw.coin() ? Map::ScaleUp : Map::ScaleDown;
  e.nominal = 1;
  e.u_max = 9;
  return e;
}

const std::vector<Family> kListFamilies = {Family::BlockStiffness, Family::BlockMass,   Family::JointComponent,
                                           Family::Support,        Family::SensorMass,  Family::BetweenParts,
                                           Family::NodeSet,        Family::SurfaceNode, Family::RegionScale,
                                           Family::Poisson};
const std::vector<Family> kOutsideFamilies = {Family::AnyNodeMass, Family::AnyNodeSpring, Family::PartialBlock};

struct DrawOptions {
  double min_shift = 0.002, max_shift = 0.05;
  std::optional<Category> only;
};

Case draw_case(ProblemContext& ctx, int number, std::uint64_t seed, bool force_control, const DrawOptions& options) {
  Case c;
  c.number = number;
  c.seed = seed;
  detail::Uniform uniform(seed);
  Drawer draw{uniform};
  c.noise_seed = static_cast<std::uint64_t>(uniform(0, 1) * 4294967296.0) + 1;
  double x = uniform(0, 1);
  c.category = kCategoryWeights.back().first;
  for (const auto& [category, weight] : kCategoryWeights) {
    if (x < weight) {
      c.category = category;
      break;
    }
    x -= weight;
  }
  if (options.only) c.category = *options.only;
  if (force_control) c.category = Category::Control;
  if (ctx.fine_ratios.empty() && !options.only) {  // a mesh read from a file: no finer truth
    if (c.category == Category::FineControl) c.category = Category::Control;
    if (c.category == Category::FineEffect) c.category = Category::Single;
  }

  auto available = [&](const std::vector<Family>& families) {
    std::vector<Family> out;
    for (Family f : families) {
      if (!outside_list(f) && !ctx.family_candidates.count(f)) continue;
      out.push_back(f);
    }
    return out;
  };
  const std::vector<Family> in_list = available(kListFamilies), outside = available(kOutsideFamilies);
  std::vector<Family> any = in_list;
  any.insert(any.end(), outside.begin(), outside.end());
  // An effect sized at the bound of its candidate's range (its shift saturates below the target,
  // e.g. a support already nearly free or a foam block's mass) or below half the range's lower end
  // is drawn again, at most twice, so that the drawn range is what the cases get.
  auto add_effect = [&](const std::vector<Family>& families, double lo, double hi) {
    int saturated = 0;
    for (int attempt = 0; attempt < 20; ++attempt) {
      const Family f = families[draw.index(static_cast<int>(families.size()))];
      std::optional<EffectSpec> e = draw_effect(ctx, f, draw.log_uniform(lo, hi), draw);
      if (!e) continue;
      const bool clash = std::any_of(c.effects.begin(), c.effects.end(), [&](const EffectSpec& o) {
        return o.name == e->name || (!o.block.empty() && o.block == e->block);
      });
      if (clash) continue;
      size_effect(ctx, &*e);
      if ((e->shift < 0.5 * lo || e->u == e->u_max || e->u == e->u_min) && saturated++ < 2) continue;
      c.effects.push_back(*e);
      return;
    }
  };
  switch (c.category) {
    case Category::Control:
    case Category::FineControl: break;
    case Category::Single: add_effect(in_list, options.min_shift, options.max_shift); break;
    case Category::Outside: add_effect(outside, options.min_shift, options.max_shift); break;
    case Category::Multi: {
      const int n = uniform(0, 1) < 0.5 ? 2 : 3;
      for (int k = 0; k < n; ++k) add_effect(any, options.min_shift, options.max_shift);
      break;
    }
    case Category::BelowNoise: add_effect(any, 1e-4, 1e-3); break;
    case Category::FineEffect: add_effect(any, options.min_shift, options.max_shift); break;
  }
  if (c.category == Category::FineControl || c.category == Category::FineEffect) {
    if (ctx.fine_ratios.empty()) throw std::runtime_error("no usable finer mesh");
    c.fine_ratio = ctx.fine_ratios[draw.index(static_cast<int>(ctx.fine_ratios.size()))];
  }
  return c;
}

// ---------------------------------------------------------------------------------------------
// Scoring

enum class AcceptedKind {
  BlockStiffness, BlockMass, RegionStiffness, RegionMass, Poisson, JointComponent, ExistingMass, Mass, GroundSpring,
  Support, AddedJoint, Other
};

struct Classified {
  AcceptedKind kind = AcceptedKind::Other;
  std::string entity;
  int component = -1;
};

Classified classify(const EffectCandidate& c) {
  const ModelChange& ch = c.change;
  Classified out;
  out.entity = ch.entity;
  const auto k = std::find(kStiffnessComponentNames.begin(), kStiffnessComponentNames.end(), ch.property);
  out.component = k == kStiffnessComponentNames.end() ? -1 : static_cast<int>(k - kStiffnessComponentNames.begin());
  switch (ch.kind) {
    case ModelChange::Kind::SetProperty:
      if (ch.property == "stiffness_scale") out.kind = AcceptedKind::BlockStiffness;
      else if (ch.property == "mass_scale") out.kind = AcceptedKind::BlockMass;
      else if (ch.property == "nu") out.kind = AcceptedKind::Poisson;
      else if (out.component >= 0) out.kind = AcceptedKind::JointComponent;
      else if (ch.property == "mass") out.kind = AcceptedKind::ExistingMass;
      break;
    case ModelChange::Kind::AddPointMass: out.kind = ch.property == "mass" ? AcceptedKind::Mass : AcceptedKind::Other; break;
    case ModelChange::Kind::AddSpring: out.kind = AcceptedKind::GroundSpring; break;
    case ModelChange::Kind::FlexibleSupport: out.kind = AcceptedKind::Support; break;
    case ModelChange::Kind::AddJoint: out.kind = AcceptedKind::AddedJoint; break;
    case ModelChange::Kind::AddRegion:
      out.kind = ch.property == "stiffness_scale" ? AcceptedKind::RegionStiffness : AcceptedKind::RegionMass;
      out.entity = ch.places.empty() ? "" : ch.places[0].node_set;  // the block
      break;
  }
  return out;
}

EffectCandidate as_candidate(const EffectSpec& t) {
  EffectCandidate c;
  c.name = t.name;
  c.change = t.change;
  return c;
}

/// Whether the accepted candidate `a` (acting at `where`) is the truth effect `t`: the right kind
/// and place (within two element sizes `h2` of where the truth acts).
bool kinds_match(const EffectSpec& t, const EffectCandidate& a, double value, const std::optional<Vec3>& where,
                 double h2) {
  const Classified k = classify(a);
  auto near = [&](double extra) { return where && t.location && (*where - *t.location).norm() <= h2 + extra; };
  // Mass added at a place: a point mass, or a heavier region (the library's one kind, "local mass").
  const bool mass_added = k.kind == AcceptedKind::Mass || (k.kind == AcceptedKind::RegionMass && value > 1);
  const bool stiffness_local = k.kind == AcceptedKind::GroundSpring || k.kind == AcceptedKind::Support ||
                               k.kind == AcceptedKind::AddedJoint || k.kind == AcceptedKind::JointComponent ||
                               k.kind == AcceptedKind::RegionStiffness;
  switch (t.family) {
    case Family::BlockStiffness: return k.kind == AcceptedKind::BlockStiffness && k.entity == t.block;
    case Family::BlockMass: return k.kind == AcceptedKind::BlockMass && k.entity == t.block;
    case Family::JointComponent:
    case Family::Support: return a.name == t.name;
    case Family::NodeSet:
    case Family::BetweenParts: {
      if (a.name == t.name) return true;
      const Classified tk = classify(as_candidate(t));
      return k.kind == tk.kind && k.component == tk.component && near(0);
    }
    case Family::RegionScale: {
      if (a.name == t.name) return true;
      const Classified tk = classify(as_candidate(t));
      if (tk.kind == AcceptedKind::RegionMass && t.value > 1 && mass_added && near(0)) return true;
      return k.kind == tk.kind && k.entity == tk.entity && near(0);
    }
    case Family::SensorMass:
    case Family::AnyNodeMass: return mass_added && near(0);
    case Family::SurfaceNode:
    case Family::AnyNodeSpring: {
      const Classified tk = classify(as_candidate(t));
      if (tk.kind == AcceptedKind::Mass) return mass_added && near(0);
      return (k.kind == AcceptedKind::GroundSpring || k.kind == AcceptedKind::Support) && k.component == tk.component && near(0);
    }
    case Family::PartialBlock:
      return (k.kind == AcceptedKind::BlockStiffness && k.entity == t.block) || (stiffness_local && near(t.region_radius));
    case Family::Poisson: return k.kind == AcceptedKind::Poisson && k.entity == t.block;
  }
  return false;
}

/// Relative error of the accepted value's change from nominal against the truth's (NaN when
/// not comparable).
double value_error(const EffectSpec& t, const EffectCandidate& a, double value) {
  if (t.family == Family::PartialBlock || t.family == Family::Poisson) return NAN;
  const Classified k = classify(a);
  if (k.kind == AcceptedKind::Support) return t.value / value - 1;  // compliance
  if (a.variable == EffectCandidate::Variable::Log) {
    const double truth_change = t.value - a.nominal;
    return truth_change == 0 ? NAN : (value - a.nominal) / truth_change - 1;
  }
  return value / t.value - 1;
}

/// The place spread the diagnosis states for the effect it named `name` (the last step or
/// exchange that put it in; DiagnosisStep::place_spread), 0 where it states none.
double stated_spread(const Diagnosis& d, const std::string& name) {
  double spread = 0;
  for (const std::vector<DiagnosisStep>* list : {&d.steps, &d.exchanges})
    for (const DiagnosisStep& s : *list)
      if (s.effect.candidate.name == name && std::isfinite(s.place_spread)) spread = s.place_spread;
  return spread;
}

/// A single effect's signal strength, lambda / lambda*, as a bin of the breakdown that shows how
/// finding the place needs more signal than the detection does ("01-02" is barely detectable).
std::string strength_bin(double ratio) {  // zero-padded: the rows print in order
  if (ratio < 1) return "00-01";
  if (ratio < 2) return "01-02";
  if (ratio < 5) return "02-05";
  if (ratio < 20) return "05-20";
  return "20 and above";
}

/// With DIAGNOSIS_BENCHMARK_TRACE: the 25 best candidates of each later screen of the kept path
/// (after each step, and where the steps stopped), to see what a later step had to choose from.
void trace_later_screens(const Diagnosis& d) {
  for (size_t k = 1; k < d.rankings.size(); ++k)
    for (size_t r = 0; r < d.rankings[k].effects.size() && r < 25; ++r) {
      const RankedEffect& x = d.rankings[k].effects[r];
      std::fprintf(stderr, "  screen %zu (chi-square %.4g) top %3zu %-48s predicted %8.2f achieved %8.2f penalty %5.2f\n",
                   k + 1, d.rankings[k].chi2_before, r + 1, x.candidate.name.c_str(), x.predicted_reduction,
                   x.achieved_reduction, x.kind_penalty);
    }
}

/// With DIAGNOSIS_BENCHMARK_TRACE: every candidate of the first step's ranking that would count as
/// the truth's kind and place (at its refit or predicted value), with its rank, prediction, refit
/// and kind penalty: where the right answer stood when the loop chose another.
void trace_right_candidates(const ProblemContext& ctx, const Case& c, const Diagnosis& d) {
  for (size_t r = 0; r < d.ranking.effects.size() && r < 40; ++r) {
    const RankedEffect& x = d.ranking.effects[r];
    std::fprintf(stderr, "  top %4zu %-48s predicted %8.2f achieved %8.2f penalty %5.2f value %.4g\n", r + 1,
                 x.candidate.name.c_str(), x.predicted_reduction, x.achieved_reduction, x.kind_penalty,
                 x.refitted ? x.value : x.predicted_value);
  }
  for (const EffectSpec& e : c.effects) {
    const double h2 = 2 * (e.location ? element_size_at(ctx, *e.location) : 0);
    int shown = 0;
    for (size_t r = 0; r < d.ranking.effects.size() && shown < 8; ++r) {
      const RankedEffect& x = d.ranking.effects[r];
      const double value = x.refitted ? x.value : x.predicted_value;
      if (!kinds_match(e, x.candidate, value, effect_location(ctx.problem.model, x.candidate), h2)) continue;
      ++shown;
      std::fprintf(stderr, "  right %-12s rank %4zu %-48s predicted %8.2f achieved %8.2f penalty %5.2f value %.4g\n",
                   e.name.c_str(), r + 1, x.candidate.name.c_str(), x.predicted_reduction, x.achieved_reduction,
                   x.kind_penalty, value);
    }
  }
}

/// A number for the JSON, null when it is not finite (JSON has no NaN).
json finite_or_null(double v) { return std::isfinite(v) ? json(v) : json(); }

struct Outcome {
  bool ran = false;
  bool flagged = false;
  std::vector<std::string> accepted;      // kept
  std::vector<std::string> accepted_values;
  json accepted_locations = json::array();
  int steps = 0, dropped = 0, exchanges = 0;
  bool first_right = false, all_found = false;
  bool named_right = false;  // the first step's effect or one of its alternatives is a truth effect
  bool within_spread = false;  // the first kept effect's kind is right, its place within its stated spread
  int spurious = 0;  // kept effects that match no truth effect
  double p_before = NAN, p_final = NAN, chi2_before = NAN, chi2_final = NAN;
  double chi2_truth = NAN;  // truth_model_chi2(), for truths on the problem's own mesh
  int truth_effects = 0;
  double critical_value = NAN;  // of the first step's likelihood-ratio test
  double value_error = NAN;
  double wall = 0, cpu = 0, case_wall = 0, case_cpu = 0;
  std::string recommendation;
  json steps_json = json::array();
  json mesh_check;  // the discretization estimate's verdict and the two loops' scores; null without
};

// ---------------------------------------------------------------------------------------------

struct Args {
  std::vector<std::string> problems;
  std::vector<int> cases = {20}, controls = {0};
  std::uint64_t seed_base = 2000;
  std::string json_path;
  double significance = 0.01;
  MeasurementNoise noise{0.002, 0.02, 1};
  DrawOptions draw;
  bool dry_run = false;
  std::string write_data;  // --write-data: each case's data file and problem file in this folder
  std::vector<int> only_cases;  // --case-list: run only these case numbers
  std::vector<double> fine_ratios = {1.5, 2.0};
  int refits = RankingOptions().refits;
  int weak_refits = RankingOptions().weak_refits;
  int place_refits = RankingOptions().place_refits;
  int kind_refits = RankingOptions().kind_refits;
  int neighbour_refits = RankingOptions().neighbour_refits;
  int neighbour_rounds = RankingOptions().neighbour_rounds;
  int first_step_alternatives = DiagnosisOptions().first_step_alternatives;
  bool alternatives_after_consistent_end = DiagnosisOptions().alternatives_after_consistent_end;
  double other_data_margin = DiagnosisOptions().other_data_margin;
  int pair_exchanges = DiagnosisOptions().pair_exchanges;
  int calibration_starts = DiagnosisOptions().calibration_starts;
  int region_levels = CandidateOptions().region_levels;
  bool region_stagger = CandidateOptions().region_stagger;
  double region_elements = CandidateOptions().region_elements;
  double refit_function_tolerance = RankingOptions::default_refit_options().function_tolerance;
  double refit_span_share = RankingOptions().refit_span_share;
  bool equal_kind_prior = RankingOptions().equal_kind_prior;
  bool stop_when_consistent = DiagnosisOptions().stop_when_consistent;
  bool print_diagnosis = false;
  double mesh_check = 1.5;  // as `diagnose --mesh-check`: the discretization estimate's finer mesh; 0: none
  int jobs = 1;             // refits at a time in threads (run_in_threads), as `diagnose --jobs`
  bool walks_in_turn = false;  // as `diagnose --walks-in-turn`
  std::string command;
};

void usage() {
  std::puts(
      "diagnosis_benchmark [--problem PATH]... [--cases N[,N..]] [--controls M[,M..]] [--seed-base B]\n"
      "                    [--json FILE] [--significance A] [--noise-freq F] [--noise-shape S]\n"
      "                    [--min-shift X] [--max-shift X] [--only CATEGORY] [--case-list K,..] [--dry-run]\n"
      "                    [--write-data DIR]\n"
      "                    [--mesh-check R] [--refits N] [--weak-refits N] [--place-refits N] [--kind-refits N] [--neighbour-refits N]\n"
      "                    [--neighbour-rounds N] [--no-kind-prior] [--first-step-alternatives N] [--pair-exchanges N]\n"
      "                    [--calibration-starts N] [--alternatives-after-consistent-end 0|1] [--other-data-margin X]\n"
      "                    [--print-diagnosis] [--stop-when-consistent] [--jobs N] [--walks-in-turn] [--region-levels N]\n"
      "                    [--no-region-stagger]\n"
      "                    [--region-size X] [--refit-function-tolerance X]\n"
      "                    [--refit-span-share X]\n"
      "  --refits, --weak-refits, --place-refits, --kind-refits, --neighbour-refits, --neighbour-rounds,\n"
      "  --no-kind-prior: RankingOptions::refits, weak_refits, place_refits, kind_refits, neighbour_refits,\n"
      "  neighbour_rounds and\n"
      "  equal_kind_prior; --first-step-alternatives, --pair-exchanges, --calibration-starts:\n"
      "  DiagnosisOptions::first_step_alternatives, pair_exchanges and calibration_starts (defaults:\n"
      "  diagnose's); --alternatives-after-consistent-end: DiagnosisOptions::\n"
      "  alternatives_after_consistent_end; --other-data-margin: DiagnosisOptions::other_data_margin;\n"
      "  --print-diagnosis: each case's diagnose report on stderr;\n"
      "  --write-data DIR: each case's data file and a problem file reading it (case-SEED.yaml, on\n"
      "  the --problem file) in DIR, for `fullspace_calib diagnose`; with --dry-run, no diagnosis;\n"
      "  --region-levels: CandidateOptions::region_levels, the grids of block regions screened (the\n"
      "  cases are drawn from the finest grid's whatever it is); --region-size:\n"
      "  CandidateOptions::region_elements, the finest regions' size in element sizes (the cases are\n"
      "  drawn from regions of the default size whatever it is); --no-region-stagger:\n"
      "  CandidateOptions::region_stagger off, no shifted grids;\n"
      "  --refit-function-tolerance: RankingOptions::refit.function_tolerance; --refit-span-share:\n"
      "  RankingOptions::refit_span_share (0: every refit on the whole model);\n"
      "  DIAGNOSIS_BENCHMARK_TRACE=1 (environment): the sizing of each truth, and per case the first\n"
      "  step's 40 best candidates and the 8 best of those that would count as right, and each later\n"
      "  screen's 25 best;\n"
      "  --jobs: refits at a time, each in a thread, and above 1 the paths that do not depend on one\n"
      "  another side by side (--walks-in-turn: not), as diagnose (default 1: the cpu s column is then\n"
      "  one core's);\n"
      "  --mesh-check: the diagnosis's discretization estimate on a mesh R times finer, as diagnose's\n"
      "  default (1.5); 0 leaves it out;\n"
      "  --cases, --controls: per problem (one value for all, or one per --problem in order);\n"
      "  --controls adds M control cases per problem after the N drawn ones (cheap false-alarm counts);\n"
      "  --case-list: run only these case numbers (with the same --cases/--controls: reproduces them);\n"
      "  CATEGORY: control single outside multi below-noise fine-control fine-effect (on a mesh read from a\n"
      "  file, which has no finer truth, drawn fine-mesh cases become controls and single effects).\n"
      "  Case k of problem j has seed B + 1000 j + k. Tuning runs: --seed-base 1000; reports: 2000.");
}

int list_value(const std::vector<int>& values, size_t j) { return values.size() == 1 ? values[0] : values.at(j); }

std::string json_number(double v) { return std::isfinite(v) ? format("%.6g", v) : "-"; }

double median(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

struct Row {
  int n = 0, detectable = 0, flagged_detectable = 0, flagged_all = 0, right = 0, named = 0, all_found = 0, multi_detectable = 0,
      consistent = 0, any_accepted = 0, errors = 0, consistent_all = 0;
  // Multi-effect cases each of whose effects the data tell given the others, and of them those
  // whose every effect was found.
  int multi_given_others = 0, all_found_given_others = 0;
  // Detectable cases on the problem's mesh whose first accepted effect is not the truth, and of
  // them those whose data favour the truth model by 20 : 1 or more (data_favour_truth()).
  int missed = 0, missed_data_favour_truth = 0;
  // Detectable cases whose first kept effect has the right kind and lies within the place spread
  // the diagnosis states for it (DiagnosisStep::place_spread) plus the place tolerance.
  int within_spread = 0;
  std::vector<double> p_final, p_all, value_errors, wall, cpu;
};

/// The data favour the truth model over the diagnosis's final model by a likelihood ratio of
/// 20 : 1 or more, beyond what the loop's test asks of each effect the truth has more: its
/// chi-square, less one for each accepted value the final model fits and it does not, lies
/// 2 ln 20 = 6, plus the critical value per further effect, or more below the final one.
bool data_favour_truth(const Outcome& o) {
  const double fitted = static_cast<double>(o.accepted.size());
  const int more = std::max(0, o.truth_effects - static_cast<int>(o.accepted.size()));
  const double margin = 6 + (more > 0 ? more * o.critical_value : 0);
  return std::isfinite(o.chi2_truth) && o.chi2_final - (o.chi2_truth - fitted) >= margin;
}

std::string pct(int a, int b) { return b == 0 ? "-" : format("%.0f%%", 100.0 * a / b) + " (" + std::to_string(a) + "/" + std::to_string(b) + ")"; }

}  // namespace

int main(int argc, char** argv) {
  Args args;
  for (int i = 0; i < argc; ++i) args.command += (i ? " " : "") + std::string(argv[i]);
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      auto next = [&]() -> std::string {
        if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
        return argv[++i];
      };
      if (a == "--problem") args.problems.push_back(next());
      else if (a == "--cases" || a == "--controls") {
        std::vector<int> values;
        for (double v : bench::parse_list(next())) values.push_back(static_cast<int>(v));
        (a == "--cases" ? args.cases : args.controls) = values;
      } else if (a == "--seed-base") args.seed_base = std::stoull(next());
      else if (a == "--json") args.json_path = next();
      else if (a == "--significance") args.significance = std::stod(next());
      else if (a == "--mesh-check") args.mesh_check = std::stod(next());
      else if (a == "--refits") args.refits = std::stoi(next());
      else if (a == "--weak-refits") args.weak_refits = std::stoi(next());
      else if (a == "--place-refits") args.place_refits = std::stoi(next());
      else if (a == "--kind-refits") args.kind_refits = std::stoi(next());
      else if (a == "--neighbour-refits") args.neighbour_refits = std::stoi(next());
      else if (a == "--neighbour-rounds") args.neighbour_rounds = std::stoi(next());
      else if (a == "--first-step-alternatives") args.first_step_alternatives = std::stoi(next());
      else if (a == "--alternatives-after-consistent-end") args.alternatives_after_consistent_end = std::stoi(next()) != 0;
      else if (a == "--other-data-margin") args.other_data_margin = std::stod(next());
      else if (a == "--pair-exchanges") args.pair_exchanges = std::stoi(next());
      else if (a == "--calibration-starts") args.calibration_starts = std::stoi(next());
      else if (a == "--no-region-stagger") args.region_stagger = false;
      else if (a == "--region-levels") {
        CandidateOptions candidates;
        candidates.region_levels = args.region_levels = std::stoi(next());
        std::string why;
        if (!candidates.IsValid(&why)) throw std::invalid_argument("--region-levels: " + why);
      }
      else if (a == "--region-size") {
        CandidateOptions candidates;
        candidates.region_elements = args.region_elements = std::stod(next());
        std::string why;
        if (!candidates.IsValid(&why)) throw std::invalid_argument("--region-size: " + why);
      }
      else if (a == "--refit-function-tolerance") args.refit_function_tolerance = std::stod(next());
      else if (a == "--refit-span-share") args.refit_span_share = std::stod(next());
      else if (a == "--no-kind-prior") args.equal_kind_prior = false;
      else if (a == "--stop-when-consistent") args.stop_when_consistent = true;
      else if (a == "--jobs") args.jobs = std::stoi(next());
      else if (a == "--walks-in-turn") args.walks_in_turn = true;
      else if (a == "--print-diagnosis") args.print_diagnosis = true;
      else if (a == "--noise-freq") args.noise.frequency = std::stod(next());
      else if (a == "--noise-shape") args.noise.shape = std::stod(next());
      else if (a == "--min-shift") args.draw.min_shift = std::stod(next());
      else if (a == "--max-shift") args.draw.max_shift = std::stod(next());
      else if (a == "--dry-run") args.dry_run = true;
      else if (a == "--write-data") args.write_data = next();
      else if (a == "--case-list")
        for (double v : bench::parse_list(next())) args.only_cases.push_back(static_cast<int>(v));
      else if (a == "--only") {
        const std::string key = next();
        for (const auto& [c, w] : kCategoryWeights)
          if (key == category_key(c)) args.draw.only = c;
        if (!args.draw.only) throw std::invalid_argument("--only " + key + ": unknown category");
      } else if (a == "--help" || a == "-h") {
        usage();
        return 0;
      } else {
        throw std::invalid_argument("unknown argument " + a + " (--help)");
      }
    }
    // Detectability and the scores weight by the noise: noise-free data are diagnose's own case
    // (its --resolution), not this benchmark's.
    if (!(args.noise.frequency > 0) || !(args.noise.shape >= 0))
      throw std::invalid_argument("--noise-freq must be > 0 and --noise-shape >= 0: the cases are scored against the noise");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
  if (args.problems.empty())
    args.problems = {std::string(MODALCAL_SOURCE_DIR) + "/problems/portal-frame/synthetic.yaml",
                     std::string(MODALCAL_SOURCE_DIR) + "/problems/lfu-hidden/nominal.yaml"};

  const std::string commit = run_command("git -C " + std::string(MODALCAL_SOURCE_DIR) + " rev-parse --short HEAD");
  const std::string dirty = run_command("git -C " + std::string(MODALCAL_SOURCE_DIR) + " status --porcelain -- src include");
  char date[64];
  const std::time_t now = std::time(nullptr);
  std::strftime(date, sizeof date, "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
  std::printf("# model-form diagnosis on generated cases\n# commit %s%s, %s, load average %s\n# %s\n",
              commit.c_str(), dirty.empty() ? "" : " (library sources modified)", date, bench::load_average().c_str(),
              args.command.c_str());
  std::printf("# DiagnosisOptions (refits %d, %d when weak, + %d at places apart + %d of other kinds + %d neighbours in up to %d rounds, %d other first steps%s, %d pair exchanges, %d grids of regions%s, %d further calibration starts%s%s, other data's margin %g, significance %g, max_steps %d, backward pass); noise %g "
              "(frequency), %g (shape); start: the problem file's initial values\n",
              args.refits, args.weak_refits, args.place_refits, args.kind_refits, args.neighbour_refits, args.neighbour_rounds, args.first_step_alternatives, args.alternatives_after_consistent_end ? "" : " (only after an end above the noise)", args.pair_exchanges, args.region_levels, args.region_stagger ? " and each shifted" : "", args.calibration_starts, args.equal_kind_prior ? "" : ", no kind prior",
              args.stop_when_consistent ? ", stop when consistent" : "", args.other_data_margin, args.significance, DiagnosisOptions().max_steps, args.noise.frequency,
              args.noise.shape);
  std::printf("# detectable: lambda = |(I - J J^+) r|^2 >= lambda*, r the noise-weighted residual of the nominal model at the "
              "true parameters against noise-free truth data, J its Jacobian in the parameters (what calibration absorbs, "
              "first order); lambda* = (sqrt(c) + 1.2816)^2, c = chi2_1 critical value at alpha/N candidates: 90 %% power "
              "of the first step's Bonferroni test; multi-effect cases: every effect alone; given the others: every effect "
              "with the others in the model, refitted to noise-free truth data\n");
  std::printf("# sizes: largest noise-free frequency shift drawn log-uniform in [%g, %g] (below noise: [1e-4, 1e-3]), "
              "value set by secant/bisection on forward solves; part of a block: the truth's block split in two (a "
              "ball of elements, no candidate region)\n",
              args.draw.min_shift, args.draw.max_shift);
  std::fflush(stdout);

  json cases_json = json::array();
  std::map<std::string, Row> rows, family_rows, strength_rows;
  std::vector<std::string> row_order;
  auto row = [&](std::map<std::string, Row>& m, const std::string& key) -> Row& {
    if (&m == &rows && std::find(row_order.begin(), row_order.end(), key) == row_order.end()) row_order.push_back(key);
    return m[key];
  };
  Row single_rows, outside_rows, multi_rows, controls_row, fine_controls_row, detectable_effect_rows;
  // Per problem, its slowest diagnosis: the wall seconds and the case number.
  std::vector<std::pair<double, int>> slowest(args.problems.size(), {0.0, -1});
  const auto t_all = Clock::now();
  const double cpu_all = cpu_seconds();

  for (size_t j = 0; j < args.problems.size(); ++j) {
    const std::string& path = args.problems[j];
    std::printf("\n## %s\n", path.c_str());
    ProblemContext ctx = make_context(path, args.noise);
    {
      const int N = static_cast<int>(ctx.candidates.size());
      ctx.critical = chi_square_critical_value(args.significance / N, 1);
      ctx.lambda_star = std::pow(std::sqrt(ctx.critical) + 1.2816, 2);
      std::printf("# %d parameters, %zu measured modes%s, %d DOF-nodes, refinement %g; %d candidates; detectable: "
                  "lambda >= lambda* = (sqrt(%.3g) + 1.2816)^2 = %.3g\n",
                  static_cast<int>(ctx.problem.parameters.size()), ctx.problem.measured.size(),
                  ctx.synthesis.shapes ? " with shapes" : "", ctx.problem.model.num_nodes(), ctx.refinement, N,
                  ctx.critical, ctx.lambda_star);
      std::printf("# families:");
      for (const auto& [f, list] : ctx.family_candidates) std::printf(" %s (%zu)", family_name(f), list.size());
      std::printf("\n");
    }
    find_fine_ratios(&ctx, args.fine_ratios);
    if (args.mesh_check > 0) {  // what `diagnose` loads for its default --mesh-check
      LoadOptions load;
      load.refinement = ctx.refinement * args.mesh_check;
      load.nearest_sensor_nodes = true;
      try {
        ctx.check = load_problem(ctx.path, load);
        synthesize_measured(&*ctx.check);
        std::printf("# discretization estimate on a mesh x%g: %d nodes\n", args.mesh_check, ctx.check->model.num_nodes());
      } catch (const ProblemError& e) {  // as diagnose: a mesh read from a file is not refined
        ctx.check.reset();
        std::printf("# no discretization estimate: %s\n", e.what());
      }
    }
    const int n_cases = list_value(args.cases, j), n_controls = list_value(args.controls, j);
    std::printf("%-5s %-6s %-26s %-7s %-8s %-34s %-7s %-6s %-9s %-9s %s\n", "case", "seed", "category", "lambda", "detect",
                "truth", "flag", "right", "p final", "cpu s", "accepted");
    std::fflush(stdout);
    for (int k = 0; k < n_cases + n_controls; ++k) {
      if (!args.only_cases.empty() && std::find(args.only_cases.begin(), args.only_cases.end(), k) == args.only_cases.end())
        continue;
      const std::uint64_t seed = args.seed_base + 1000 * j + static_cast<std::uint64_t>(k);
      const auto t_case = Clock::now();
      const double cpu_case = cpu_seconds();
      Case c;
      Outcome o;
      json cj;
      try {
        c = draw_case(ctx, k, seed, k >= n_cases, args.draw);
        // Each effect alone (sized when drawn): its detectability on the problem's mesh.
        std::vector<Signature> alone;
        for (EffectSpec& e : c.effects) {
          alone.push_back(signature(ctx, synthesize(ctx, build_truth(ctx, ctx.problem, {e}), MeasurementNoise{}, true)));
          e.lambda = noncentrality(alone.back());
        }
        if (c.effects.size() > 1) {
          const std::vector<double> given = noncentrality_given_others(alone);
          for (size_t i = 0; i < c.effects.size(); ++i) c.effects[i].lambda_given_others = given[i];
        }
        const Problem& mesh = c.fine_ratio > 0 ? ctx.fine.at(c.fine_ratio) : ctx.problem;
        const TruthModel truth = build_truth(ctx, mesh, c.effects);
        if (c.effects.size() > 1 && c.fine_ratio == 0) {
          const std::vector<double> refit =
              noncentrality_given_others_refit(ctx, c.effects, synthesize(ctx, truth, MeasurementNoise{}, true));
          for (size_t i = 0; i < c.effects.size(); ++i) c.effects[i].lambda_given_others_refit = refit[i];
        }
        c.lambda_case = c.effects.size() == 1 && c.fine_ratio == 0
                            ? c.effects[0].lambda
                            : noncentrality(signature(ctx, synthesize(ctx, truth, MeasurementNoise{}, true, &mesh)));
        c.detectable = !c.effects.empty() && std::all_of(c.effects.begin(), c.effects.end(), [&](const EffectSpec& e) {
          return e.lambda >= ctx.lambda_star;
        });
        c.detectable_given_others = c.detectable && (c.effects.size() == 1 || std::all_of(c.effects.begin(), c.effects.end(), [&](const EffectSpec& e) {
                                      return (std::isfinite(e.lambda_given_others_refit) ? e.lambda_given_others_refit
                                                                                          : e.lambda_given_others) >= ctx.lambda_star;
                                    }));
        MeasurementNoise noise = args.noise;
        noise.seed = c.noise_seed;
        const MeasuredData data = synthesize(ctx, truth, noise, true, &mesh);
        Problem problem = ctx.problem;
        problem.measured = data.modes;
        problem.synthetic.reset();
        problem.measurement_noise = data.noise;
        problem.synthetic_truth = data.truth;
        if (!args.write_data.empty()) write_case(args.write_data, ctx.path, c.seed, data);
        if (!args.dry_run) {
          DiagnosisOptions options;
          options.ranking.significance = args.significance;
          options.ranking.refits = args.refits;
          options.ranking.weak_refits = args.weak_refits;
          options.ranking.place_refits = args.place_refits;
          options.ranking.kind_refits = args.kind_refits;
          options.ranking.neighbour_refits = args.neighbour_refits;
          options.ranking.neighbour_rounds = args.neighbour_rounds;
          options.first_step_alternatives = args.first_step_alternatives;
          options.alternatives_after_consistent_end = args.alternatives_after_consistent_end;
          options.other_data_margin = args.other_data_margin;
          options.pair_exchanges = args.pair_exchanges;
          options.calibration_starts = args.calibration_starts;
          options.candidates.region_levels = args.region_levels;
          options.candidates.region_stagger = args.region_stagger;
          options.candidates.region_elements = args.region_elements;
          options.ranking.refit.function_tolerance = args.refit_function_tolerance;
          options.ranking.refit_span_share = args.refit_span_share;
          options.ranking.equal_kind_prior = args.equal_kind_prior;
          options.stop_when_consistent = args.stop_when_consistent;
          options.ranking.task_map = run_in_threads(args.jobs);
          options.walk_side_by_side = args.jobs > 1 && !args.walks_in_turn;  // as diagnose run alone
          options.test.significance = args.significance;
          if (ctx.check) options.finer_mesh = &*ctx.check;
          const auto t0 = Clock::now();
          const double cpu0 = cpu_seconds();
          const Diagnosis d = diagnose(problem, problem.initial_values(), options);
          o.wall = seconds_since(t0);
          o.cpu = cpu_seconds() - cpu0;
          o.ran = true;
          o.flagged = d.model_form_error;
          o.steps = static_cast<int>(d.steps.size());
          o.dropped = static_cast<int>(d.dropped.size());
          o.p_before = d.before.test ? d.before.test->p_value : NAN;
          o.chi2_before = d.before.statistic;
          o.p_final = d.final_fit.test ? d.final_fit.test->p_value : NAN;
          o.chi2_final = d.final_fit.statistic;
          o.recommendation = d.recommendation;
          if (d.discretization) {
            const DiscretizationEstimate& e = *d.discretization;
            o.mesh_check = {{"significant", e.significant}, {"corrected", e.corrected},
                            {"score_corrected", finite_or_null(e.score_corrected)},
                            {"score_as_measured", finite_or_null(e.score_as_measured)},
                            {"other_data_first_path_only", e.other_data_first_path_only},
                            {"other_data_forward_steps_only", e.other_data_forward_steps_only}};
          }
          const int np = static_cast<int>(problem.parameters.size());
          std::vector<std::pair<const EffectCandidate*, double>> kept;
          const std::vector<std::string> accepted = d.accepted();
          o.exchanges = static_cast<int>(d.exchanges.size());
          for (size_t m = 0; m < d.effects.size(); ++m)
            if (std::count(accepted.begin(), accepted.end(), d.effects[m].name))
              kept.emplace_back(&d.effects[m], d.final_parameters[np + static_cast<Eigen::Index>(m)]);
          for (const auto& [cand, value] : kept) {
            o.accepted.push_back(cand->name);
            o.accepted_values.push_back(format("%.4g", value));
            const std::optional<Vec3> where = effect_location(problem.model, *cand);
            o.accepted_locations.push_back(where ? json{(*where)[0], (*where)[1], (*where)[2]} : json());
          }
          std::vector<bool> found(c.effects.size(), false);
          for (size_t m = 0; m < kept.size(); ++m) {
            const EffectCandidate& a = *kept[m].first;
            const std::optional<Vec3> where = effect_location(problem.model, a);
            bool matched = false;
            for (size_t t = 0; t < c.effects.size(); ++t) {
              const EffectSpec& e = c.effects[t];
              const double h2 = 2 * (e.location ? element_size_at(ctx, *e.location) : 0);
              if (m == 0 && kinds_match(e, a, kept[m].second, where, h2 + stated_spread(d, a.name)))
                o.within_spread = true;
              if (!kinds_match(e, a, kept[m].second, where, h2)) continue;
              matched = true;
              found[t] = true;
              if (m == 0) {
                o.first_right = o.within_spread = true;
                o.value_error = value_error(e, a, kept[m].second);
              }
            }
            if (!matched) ++o.spurious;
          }
          o.all_found = !c.effects.empty() && std::all_of(found.begin(), found.end(), [](bool b) { return b; });
          if (std::getenv("DIAGNOSIS_BENCHMARK_TRACE")) {
            trace_right_candidates(ctx, c, d);
            trace_later_screens(d);
          }
          if (!d.steps.empty()) {
            std::vector<const RankedEffect*> named = {&d.steps[0].effect};
            for (const RankedEffect& alt : d.steps[0].alternatives) named.push_back(&alt);
            for (const RankedEffect* r : named)
              for (const EffectSpec& e : c.effects) {
                const double h2 = 2 * (e.location ? element_size_at(ctx, *e.location) : 0);
                if (kinds_match(e, r->candidate, r->value, effect_location(problem.model, r->candidate), h2))
                  o.named_right = true;
              }
          }
          if (c.fine_ratio == 0 && !c.effects.empty()) o.chi2_truth = truth_model_chi2(problem, truth, data);
          o.truth_effects = static_cast<int>(c.effects.size());
          o.critical_value = d.rankings.empty() ? NAN : d.rankings.front().critical_value;
          if (args.print_diagnosis) std::fprintf(stderr, "=== case %d\n%s\n", k, format_diagnosis(problem, d).c_str());
          for (const DiagnosisStep& s : d.steps) {
            json sj;
            sj["effect"] = s.effect.candidate.name;
            sj["value"] = s.effect.value;
            sj["chi2_before"] = s.chi2_before;
            sj["chi2_after"] = s.effect.chi2_after;
            sj["achieved_reduction"] = s.effect.achieved_reduction;
            sj["critical_value"] = s.critical_value;
            sj["screened"] = s.screened;
            if (s.location) sj["location"] = {(*s.location)[0], (*s.location)[1], (*s.location)[2]};
            o.steps_json.push_back(sj);
          }
          for (const DiagnosisStep& x : d.exchanges)
            o.steps_json.push_back({{"exchanged", x.replaces}, {"for", x.effect.candidate.name}, {"score", x.effect.score()},
                                    {"replaced_score", x.replaced_score}});
          for (const DroppedEffect& x : d.dropped)
            o.steps_json.push_back({{"dropped", x.name}, {"chi2_increase", x.chi2_increase}, {"on_bound", x.on_bound}});
          for (const DiagnosisPath& x : d.paths) {
            const int rank = rank_of(d.ranking, x.first);  // its first effect in the first screen
            o.steps_json.push_back({{"path", x.first}, {"score", x.score}, {"kept", x.kept}, {"joined_after", x.joined_after},
                                    {"no_second_step", x.no_second_step}, {"first_rank", rank},
                                    {"first_statistic", rank > 0 ? d.ranking.effects[rank - 1].statistic : NAN},
                                    {"first_score", rank > 0 ? d.ranking.effects[rank - 1].score() : NAN}});
          }
        }
      } catch (const std::exception& e) {
        c.error = e.what();
      }
      o.case_wall = seconds_since(t_case);
      o.case_cpu = cpu_seconds() - cpu_case;

      // One line per case.
      std::string truth_text;
      for (const EffectSpec& e : c.effects) truth_text += (truth_text.empty() ? "" : " + ") + e.name;
      if (c.fine_ratio > 0) truth_text += (truth_text.empty() ? "" : " ") + std::string("mesh x") + format("%.3g", c.fine_ratio);
      if (truth_text.empty()) truth_text = "-";
      std::string accepted_text;
      for (size_t m = 0; m < o.accepted.size(); ++m) accepted_text += (m ? ", " : "") + o.accepted[m] + "=" + o.accepted_values[m];
      if (!c.error.empty()) accepted_text = "ERROR: " + c.error;
      std::printf("%-5d %-6llu %-26s %-7s %-8s %-34s %-7s %-6s %-9s %-9.1f %s\n", k, static_cast<unsigned long long>(seed),
                  category_key(c.category), json_number(c.lambda_case).c_str(),
                  c.effects.empty() ? "-" : (c.detectable ? "yes" : "no"), truth_text.c_str(),
                  o.ran ? (o.flagged ? "flag" : "ok") : "-", c.effects.empty() || !o.ran ? "-" : (o.first_right ? "yes" : "no"),
                  json_number(o.p_final).c_str(), o.case_cpu, accepted_text.c_str());
      std::fflush(stdout);

      cj["problem"] = path;
      cj["case"] = k;
      cj["seed"] = seed;
      cj["noise_seed"] = c.noise_seed;
      cj["category"] = category_key(c.category);
      if (c.fine_ratio > 0) cj["truth_mesh_refinement"] = c.fine_ratio * ctx.refinement;
      json effects = json::array();
      for (const EffectSpec& e : c.effects)
        effects.push_back({{"family", family_name(e.family)}, {"name", e.name}, {"change", e.text()},
                           {"in_candidate_list", e.in_list}, {"target_shift", e.target_shift}, {"shift", e.shift},
                           {"sizing_solves", e.sizing_solves}, {"lambda", e.lambda},
                           {"lambda_given_others", e.lambda_given_others},
                           {"lambda_given_others_refit", finite_or_null(e.lambda_given_others_refit)},
                           {"location", e.location ? json{(*e.location)[0], (*e.location)[1], (*e.location)[2]} : json()},
                           {"place_tolerance", e.location ? 2 * element_size_at(ctx, *e.location) + e.region_radius : NAN}});
      cj["truth"] = effects;
      cj["lambda"] = c.lambda_case;
      cj["lambda_star"] = ctx.lambda_star;
      cj["detectable"] = c.detectable;
      if (c.effects.size() > 1) cj["detectable_given_others"] = c.detectable_given_others;
      if (!c.error.empty()) cj["error"] = c.error;
      if (o.ran) {
        cj["verdict"] = o.flagged ? "model-form error" : "no model-form error";
        cj["accepted"] = o.accepted;
        cj["accepted_values"] = o.accepted_values;
        cj["accepted_locations"] = o.accepted_locations;
        cj["steps"] = o.steps_json;
        cj["first_right_kind_and_place"] = o.first_right;
        cj["right_among_named"] = o.named_right;
        cj["right_within_stated_spread"] = o.within_spread;
        cj["all_found"] = o.all_found;
        cj["spurious"] = o.spurious;
        cj["p_before"] = o.p_before;
        cj["p_final"] = o.p_final;
        cj["chi2_before"] = o.chi2_before;
        cj["chi2_final"] = o.chi2_final;
        cj["chi2_truth_model"] = finite_or_null(o.chi2_truth);
        cj["value_error"] = o.value_error;
        cj["recommendation"] = o.recommendation;
        cj["mesh_check"] = o.mesh_check;
        cj["diagnosis_wall_s"] = o.wall;
        cj["diagnosis_cpu_s"] = o.cpu;
      }
      cj["case_wall_s"] = o.case_wall;
      cj["case_cpu_s"] = o.case_cpu;
      cases_json.push_back(cj);
      if (!args.json_path.empty()) std::ofstream(args.json_path) << cases_json.dump(1) << "\n";

      // Tallies.
      if (o.ran && o.wall > slowest[j].first) slowest[j] = {o.wall, k};
      auto tally = [&](Row& r) {
        ++r.n;
        if (!c.error.empty()) {
          ++r.errors;
          return;
        }
        if (!o.ran) return;
        if (o.flagged) ++r.flagged_all;
        if (!o.accepted.empty()) ++r.any_accepted;
        r.p_all.push_back(o.p_final);
        if (o.p_final > args.significance) ++r.consistent_all;
        r.wall.push_back(o.wall);
        r.cpu.push_back(o.cpu);
        if (c.detectable) {
          ++r.detectable;
          if (o.flagged) ++r.flagged_detectable;
          if (o.first_right) ++r.right;
          if (o.named_right) ++r.named;
          if (o.within_spread) ++r.within_spread;
          if (c.effects.size() > 1) {
            ++r.multi_detectable;
            if (o.all_found) ++r.all_found;
            if (c.detectable_given_others) {
              ++r.multi_given_others;
              if (o.all_found) ++r.all_found_given_others;
            }
          }
          r.p_final.push_back(o.p_final);
          if (o.p_final > args.significance) ++r.consistent;
          if (o.first_right) r.value_errors.push_back(std::abs(o.value_error));
          const bool hit = c.effects.size() > 1 ? o.all_found : o.first_right;
          if (!hit && std::isfinite(o.chi2_truth)) {
            ++r.missed;
            if (data_favour_truth(o)) ++r.missed_data_favour_truth;
          }
        }
      };
      tally(row(rows, category_name(c.category)));
      if (c.effects.size() == 1 && (c.category == Category::Single || c.category == Category::Outside))
        tally(row(family_rows, std::string(family_name(c.effects[0].family)) +
                                   (c.effects[0].family == Family::AnyNodeMass || c.effects[0].family == Family::AnyNodeSpring
                                        ? (c.effects[0].in_list ? " (surface)" : " (interior)")
                                        : "")));
      if (c.effects.size() == 1 && (c.category == Category::Single || c.category == Category::Outside))
        tally(row(strength_rows, std::string(c.category == Category::Single ? "candidate family" : "outside the list") +
                                     ", " + strength_bin(c.lambda_case / ctx.lambda_star)));
      if (c.category == Category::Single) tally(single_rows);
      if (c.category == Category::Outside) tally(outside_rows);
      if (c.category == Category::Multi) tally(multi_rows);
      if (c.category == Category::Control) tally(controls_row);
      if (c.category == Category::FineControl) tally(fine_controls_row);
      if (!c.effects.empty()) tally(detectable_effect_rows);
    }
  }

  if (args.dry_run) return 0;
  const double a = args.significance;
  std::printf("\n## per category (all problems)\n");
  std::printf("%-34s %4s %6s %-14s %-14s %-14s %-14s %-14s %8s %-14s %9s %8s %8s %4s\n", "category", "n", "detect", "flagged",
              "right kind+place", "right named", "every effect", "any accepted", "med p", "p > alpha", "med |err|", "wall s", "cpu s", "err");
  auto print_row = [&](const std::string& name, const Row& r, bool effects) {
    std::printf("%-34s %4d %6d %-14s %-14s %-14s %-14s %-14s %8s %-14s %9s %8.1f %8.1f %4d\n", name.c_str(), r.n, r.detectable,
                effects ? pct(r.flagged_detectable, r.detectable).c_str() : pct(r.flagged_all, r.n - r.errors).c_str(),
                effects ? pct(r.right, r.detectable).c_str() : "-", effects ? pct(r.named, r.detectable).c_str() : "-",
                r.multi_detectable ? pct(r.all_found, r.multi_detectable).c_str() : "-",
                pct(r.any_accepted, r.n - r.errors).c_str(), json_number(median(effects ? r.p_final : r.p_all)).c_str(),
                effects ? pct(r.consistent, r.detectable).c_str() : pct(r.consistent_all, r.n - r.errors).c_str(), json_number(median(r.value_errors)).c_str(),
                median(r.wall), median(r.cpu), r.errors);
  };
  for (const std::string& key : row_order) {
    const bool effects = key != category_name(Category::Control) && key != category_name(Category::FineControl);
    print_row(key, rows[key], effects);
  }
  std::printf("\n## single effects by family\n");
  for (const auto& [key, r] : family_rows) print_row(key, r, true);
  std::printf("\n## single effects by signal strength, lambda / lambda*\n");
  for (const auto& [key, r] : strength_rows) print_row(key, r, true);
  std::printf("(flagged: of the detectable cases, or for controls of all; right kind+place: the first kept accepted effect; "
              "right named: the first step's effect or one of the alternatives it lists (effects the data hardly tell "
              "from it) has the right kind and place; "
              "med |err|: median relative error of the accepted value's change from nominal; wall/cpu: median per "
              "diagnosis)\n");

  auto verdict = [](bool met) { return met ? "met" : "NOT met"; };
  std::printf("\n## against the targets\n");
  const int c_n = controls_row.n - controls_row.errors;
  const double fa = c_n ? static_cast<double>(controls_row.flagged_all) / c_n : NAN;
  std::printf("%-62s %-16s %s\n", "target", "measured", "");
  std::printf("%-62s %-16s %s\n", ("false alarms <= 2 alpha = " + format("%.3g", 2 * a) + " over >= 20 controls").c_str(),
              pct(controls_row.flagged_all, c_n).c_str(), c_n < 20 ? "too few controls" : verdict(fa <= 2 * a));
  auto share_target = [&](const std::string& what, int num, int den, double target) {
    std::printf("%-62s %-16s %s\n", what.c_str(), pct(num, den).c_str(),
                den == 0 ? "no cases" : verdict(num >= target * den - 1e-9));
  };
  // The issue's identification targets, each share of the detectable cases of its kind.
  constexpr double kSinglesTarget = 0.9, kOutsideTarget = 0.8, kMultiTarget = 0.8;
  share_target("right kind and place, detectable single effects >= 90 %", single_rows.right, single_rows.detectable,
               kSinglesTarget);
  share_target("right kind and place, detectable outside the list >= 80 %", outside_rows.right, outside_rows.detectable,
               kOutsideTarget);
  share_target("every effect found, detectable multi-effect cases >= 80 %", multi_rows.all_found, multi_rows.multi_detectable,
               kMultiTarget);
  share_target("  of them, every effect detectable given the others", multi_rows.all_found_given_others,
               multi_rows.multi_given_others, kMultiTarget);
  share_target("final residual consistent with the noise, detectable >= 90 %", detectable_effect_rows.consistent,
               detectable_effect_rows.detectable, 0.9);
  const int f_n = fine_controls_row.n - fine_controls_row.errors;
  std::printf("%-62s %-16s %s\n", "physical effect accepted on <= 10 % of finer-mesh controls",
              pct(fine_controls_row.any_accepted, f_n).c_str(),
              f_n == 0 ? "no cases" : verdict(fine_controls_row.any_accepted <= 0.1 * f_n + 1e-9));
  // The issue's time bound as it states it: 3 x the 17-40 s diagnoses took on the LFU 0.7 mesh
  // before the spatial families. A wall time: it holds for a run alone on the machine, with
  // diagnose's default of one refit per core (--jobs). Wall times drift from day to day; the
  // bound measured beside the first version, on the same machine in the same hour, is
  // bench/diagnosis_time_ratio.sh's (docs/benchmarks.md, round 39).
  constexpr double kSlowestDiagnosisBound = 3 * 40.0;
  for (size_t j = 0; j < args.problems.size(); ++j)
    if (slowest[j].second >= 0)
      std::printf("%-62s %-16s %s\n", ("slowest diagnosis <= " + format("%.0f", kSlowestDiagnosisBound) + " s wall, " + args.problems[j]).c_str(),
                  (format("%.1f", slowest[j].first) + " s (case " + std::to_string(slowest[j].second) + ")").c_str(),
                  verdict(slowest[j].first <= kSlowestDiagnosisBound));
  std::printf("\n## the place as stated: right kind, the truth within the stated place spread (DiagnosisStep::place_spread) "
              "plus two element sizes\n");
  std::printf("%-62s %-16s\n", "single effects (candidate family)", pct(single_rows.within_spread, single_rows.detectable).c_str());
  std::printf("%-62s %-16s\n", "single effects (outside the list)", pct(outside_rows.within_spread, outside_rows.detectable).c_str());
  std::printf("\n## what the data could tell: misses whose data favour the truth by 20 : 1 or more\n"
              "# (the truth model's own chi-square, calibrated, less 1 per value it does not fit, at least 6 below "
              "the final one, plus the critical value for each effect it has more; detectable cases on the "
              "problem's mesh)\n");
  std::printf("%-62s %-16s\n", "single effects (candidate family)", pct(single_rows.missed_data_favour_truth, single_rows.missed).c_str());
  std::printf("%-62s %-16s\n", "single effects (outside the list)", pct(outside_rows.missed_data_favour_truth, outside_rows.missed).c_str());
  std::printf("%-62s %-16s\n", "two or three effects", pct(multi_rows.missed_data_favour_truth, multi_rows.missed).c_str());
  // A miss whose data do not favour the truth by 20 : 1 fits about as well as the truth or
  // better: a rule that answers by the data has no ground to prefer the truth there. So the
  // targets' shares cannot exceed the detectable cases less those misses.
  std::printf("\n## the data's ceiling: the detectable cases less the misses whose data do not favour the truth by 20 : 1\n"
              "# (the most a rule that answers by the data can reach on these cases; beside the target)\n");
  auto ceiling = [&](const std::string& what, const Row& r, int den, double target) {
    const int reachable = den - (r.missed - r.missed_data_favour_truth);
    std::printf("%-62s %-16s %s\n", what.c_str(), pct(reachable, den).c_str(),
                den == 0 ? "no cases" : (reachable >= target * den - 1e-9 ? "target within reach" : "target above it"));
  };
  ceiling("single effects (candidate family), target 90 %", single_rows, single_rows.detectable, kSinglesTarget);
  ceiling("single effects (outside the list), target 80 %", outside_rows, outside_rows.detectable, kOutsideTarget);
  ceiling("two or three effects, every effect, target 80 %", multi_rows, multi_rows.multi_detectable, kMultiTarget);
  std::printf("\n# total %.0f s wall, %.0f s CPU; load average %s\n", seconds_since(t_all), cpu_seconds() - cpu_all,
              bench::load_average().c_str());
  return 0;
}
