#include "moslam/experiments/online_experiment.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>

#include "moslam/common/errors.h"
#include "moslam/common/statistics.h"
#include "moslam/distributed/centralized_two_stage.h"
#include "moslam/experiments/simulated_run.h"
#include "moslam/metrics/metrics.h"
#include "moslam/solver/optimizer.h"

namespace moslam {
namespace {

using Clock = std::chrono::steady_clock;

Values RobotValues(const Values& values, int robot) {
  Values out;
  for (const auto& [k, x] : values) {
    if (k.robot == robot) out.emplace_hint(out.end(), k, x);
  }
  return out;
}

// ATE / ARE of one robot's map (its poses in `estimate`) against ground truth, aligned alone;
// nullopt while the robot's positions so far do not fix an alignment.
struct MapError {
  double ate = 0.0, are = 0.0;
};
std::optional<MapError> RobotMapError(const Values& estimate, const Values& truth, int robot) {
  Values gt;
  for (const auto& [k, x] : truth) {
    if (k.robot == robot && k.isPose() && estimate.count(k) > 0) gt.emplace(k, x);
  }
  try {
    const GroundTruthErrors e = CompareToGroundTruth(RobotValues(estimate, robot), gt);
    return MapError{e.aligned.poses.ate, e.aligned.poses.are_deg};
  } catch (const UnderdeterminedError&) {
    return std::nullopt;  // fewer than 3 non-collinear positions yet
  }
}

// The mean over the robots of their map's ATE, and how many robots it averages.
std::pair<double, int> TeamMapError(const SimulationData& data,
                                    const std::vector<ObjectSlam>& robots) {
  const Values truth = JointGroundTruth(data, robots);
  double sum = 0.0;
  int n = 0;
  for (const ObjectSlam& r : robots) {
    if (const auto e = RobotMapError(r.estimate(), truth, r.robot())) {
      sum += e->ate;
      ++n;
    }
  }
  return {n > 0 ? sum / n : std::numeric_limits<double>::quiet_NaN(), n};
}

// One run of the online mission: the robots without the team (solo), the online team with a
// point per group solve, then the batch and outlier-free references of its final factors and
// every robot's map error against them.
class OnlineMission {
 public:
  OnlineMission(const OnlineExperimentConfig& config, int run)
      : config_(config), sim_(Simulate(config.base, run)), options_(TeamOptions(config, sim_)) {
    m_.seed = sim_.seed;
  }

  OnlineRunMetrics measure() {
    const MultiRobotSlamResult solo = runSolo();
    OnlineTeam team(options_);
    MultiRobotSlamConfig online_config = sim_.slam;
    online_config.on_rendezvous =
        team.hook([&](const RendezvousGroup& g, const MultiRobotSlamResult& state) {
          record(g, state, team);
        });
    const MultiRobotSlamResult online = RunMultiRobotObjectSlam(sim_.data, online_config);
    m_.rendezvous = static_cast<double>(online.rendezvous.size());
    m_.solves = static_cast<double>(team.solves().size());
    m_.bytes_objects = static_cast<double>(online.bytes);
    for (const GroupSolveRecord& s : team.solves()) {
      m_.bytes_dgs += static_cast<double>(s.bytes);
      m_.unlinked_solves += s.unlinked ? 1.0 : 0.0;
      m_.robust_extra_bytes += static_cast<double>(s.robust_extra_bytes);
    }
    const Values batch = batchOptimum(online, team);
    const std::optional<Values> free = outlierFree(online, team);
    robotErrors(online, solo, batch, free);
    return std::move(m_);
  }

 private:
  static SimulatedRun Simulate(const ExperimentConfig& base, int run) {
    RunMetrics unused;
    return SimulateRun(base, run, unused);
  }

  static OnlineOptions TeamOptions(const OnlineExperimentConfig& config, const SimulatedRun& sim) {
    OnlineOptions options = config.online;
    options.lambda = sim.slam.rendezvous.lambda();
    if (config.base.robust) {
      RobustDgsOptions robust;  // its dgs: options.solver (OnlineOptions::robust)
      robust.gnc.threshold = config.base.gnc_threshold;
      robust.retest_left_out = config.base.retest_left_out;
      robust.retest_groups = config.base.retest_groups;
      robust.one_to_one_after_gnc = config.base.one_to_one_after_gnc;
      options.robust = robust;
    }
    return options;
  }

  // The robots without the team, and the team's map error at every step with a rendezvous.
  MultiRobotSlamResult runSolo() {
    MultiRobotSlamConfig solo_config = sim_.slam;
    solo_config.on_rendezvous = [&](const RendezvousGroup& g, MultiRobotSlamResult& team) {
      if (solo_at_step_.count(g.step) == 0) {
        solo_at_step_[g.step] = TeamMapError(sim_.data, team.robots).first;
      }
    };
    return RunMultiRobotObjectSlam(sim_.data, solo_config);
  }

  // A point per group solve of the rendezvous group `g` (after its solves).
  void record(const RendezvousGroup& g, const MultiRobotSlamResult& state, const OnlineTeam& team) {
    // The rendezvous records of this step among these robots (appended before the hook).
    double bytes_objects = 0.0;
    for (const RendezvousRecord& r : state.rendezvous) {
      if (r.event.step != g.step) continue;
      if (std::binary_search(g.robots.begin(), g.robots.end(), r.event.alpha)) {
        bytes_objects += static_cast<double>(r.bytes_alpha_to_beta + r.bytes_beta_to_alpha);
      }
    }
    const auto [team_ate, measured] = TeamMapError(sim_.data, state.robots);
    bool first = true;
    for (const GroupSolveRecord& s : team.solves()) {
      if (s.step != g.step || !std::includes(g.robots.begin(), g.robots.end(), s.robots.begin(),
                                             s.robots.end())) {
        continue;
      }
      OnlineRendezvousPoint p;
      p.step = g.step;
      p.robots = s.robots;
      p.team_ate = team_ate;
      p.solo_ate = solo_at_step_.count(g.step) > 0 ? solo_at_step_.at(g.step)
                                                   : std::numeric_limits<double>::quiet_NaN();
      p.robots_measured = measured;
      p.rotation_sweeps = s.rotation_sweeps;
      p.pose_sweeps = s.pose_sweeps;
      p.refine_steps = s.refine_steps;
      p.object_object = s.object_object;
      p.team_factors = s.team_factors;
      p.bytes_objects = first ? bytes_objects : 0.0;  // the group's messages, once
      first = false;
      p.bytes_dgs = static_cast<double>(s.bytes);
      p.bytes_point_clouds = static_cast<double>(s.robots.size()) *
                             config_.base.point_cloud.points_per_frame *
                             config_.base.point_cloud.bytes_per_point;
      p.seconds = s.seconds;
      m_.points.push_back(std::move(p));
    }
  }

  // The batch optimum of the online run's factors: the robots' final graphs and the pairs not
  // set aside (all of them in least squares). Throws UnlinkedRobotError when a robot is not
  // linked to robot 0 by those pairs.
  Values batchOptimum(const MultiRobotSlamResult& online, const OnlineTeam& team) const {
    const JointProblem joint = AssembleJointProblem(
        online.robots, AcceptedPairs(online.shared, team.setAside()), options_.lambda);
    if (!joint.unanchored_robots.empty()) {
      throw UnlinkedRobotError(fmt::format(
          "online experiment {} with {} robots, seed {}: some robot was never linked to robot 0 "
          "through the rendezvous' pairs it kept (try another seed or more poses per robot)",
          config_.base.scenario, config_.base.robots, sim_.seed));
    }
    return Optimize(joint.graph, CentralizedTwoStage(joint.graph, joint.initial).values).values;
  }

  // The outlier-free batch: the robots' final graphs without their wrong object-pose factors,
  // and the right pairs of all found (as the batch experiment's outlier-free solve); nullopt
  // when only wrong factors linked some robot (no reference for this run). Counts the wrong
  // and set-aside factors and pairs on the way.
  std::optional<Values> outlierFree(const MultiRobotSlamResult& online, const OnlineTeam& team) {
    const JointProblem all = AssembleJointProblem(online.robots, online.shared, options_.lambda);
    const std::map<Key, int> objects = LandmarkObjects(all, online.robots);
    std::vector<RelativePoseFactor> right_factors;
    // The object-pose factors: wrong when the detection is of another object than its
    // landmark's (as the batch experiment counts them); set aside when the robot's weight says so.
    std::size_t first = 0;  // the joint graph holds each robot's own graph in turn, then the pairs
    for (const ObjectSlam& r : online.robots) {
      const std::size_t n = r.numFactors();
      for (std::size_t j = 0; j < n; ++j) {
        const int object = all.factor_objects[first + j];
        const RelativePoseFactor& f = all.graph.factors()[first + j];
        if (object == ObjectSlam::kNoObservation) {
          // Odometry, and the robot's own loop-closure pairs: right unless their landmarks stand
          // for two world objects.
          const bool pair = f.a().isObject() && f.b().isObject();
          if (!pair || !WrongPair(objects, f.a(), f.b())) right_factors.push_back(f);
          continue;
        }
        const bool wrong = object < 0 || object != objects.at(f.b());
        if (!wrong) right_factors.push_back(f);
        const bool aside = j < r.factorWeights().size() && r.factorWeights()[j] < 0.5;
        m_.wrong_observations += wrong ? 1.0 : 0.0;
        m_.observations_set_aside += aside ? 1.0 : 0.0;
        m_.observations_set_aside_wrong += aside && wrong ? 1.0 : 0.0;
      }
      first += n;
    }
    for (const SharedObject& s : online.shared) {
      const bool wrong = WrongPair(objects, s.alpha_object, s.beta_object);
      m_.pairs += 1.0;
      m_.wrong_pairs += wrong ? 1.0 : 0.0;
      if (!wrong) right_factors.push_back(ObjectObjectFactor(s, options_.lambda));
    }
    for (const SharedObject& s : team.setAside()) {
      m_.set_aside += 1.0;
      m_.set_aside_wrong += WrongPair(objects, s.alpha_object, s.beta_object) ? 1.0 : 0.0;
    }
    for (const RendezvousRecord& r : online.rendezvous) m_.injected += r.injected;
    try {
      const PoseGraph free_graph(std::move(right_factors));
      return Optimize(free_graph, CentralizedTwoStage(free_graph, all.initial).values).values;
    } catch (const UnderdeterminedError&) {
      return std::nullopt;
    }
  }

  // Every robot's map (online, batch, outlier-free, solo) against ground truth, aligned alone.
  void robotErrors(const MultiRobotSlamResult& online, const MultiRobotSlamResult& solo,
                   const Values& batch, const std::optional<Values>& free) {
    const Values truth = JointGroundTruth(sim_.data, online.robots);
    for (const ObjectSlam& r : online.robots) {
      const auto on = RobotMapError(r.estimate(), truth, r.robot());
      const auto ba = RobotMapError(batch, truth, r.robot());
      const auto fr = free ? RobotMapError(*free, truth, r.robot())
                           : std::optional<MapError>(MapError{std::nan(""), std::nan("")});
      const auto so = RobotMapError(solo.robots[static_cast<std::size_t>(r.robot())].estimate(),
                                    truth, r.robot());
      if (!on || !ba || !fr || !so) {
        throw UnderdeterminedError(fmt::format(
            "online experiment: robot {} of seed {} has no three non-collinear positions",
            r.robot(), sim_.seed));
      }
      m_.online_ate.push_back(on->ate);
      m_.online_are.push_back(on->are);
      m_.batch_ate.push_back(ba->ate);
      m_.batch_are.push_back(ba->are);
      m_.solo_ate.push_back(so->ate);
      m_.free_ate.push_back(fr->ate);
      m_.worst_ratio = std::max(m_.worst_ratio, on->ate / ba->ate);
    }
  }

  const OnlineExperimentConfig& config_;
  const SimulatedRun sim_;
  const OnlineOptions options_;
  OnlineRunMetrics m_;
  std::map<int, double> solo_at_step_;  // the team's map error without the team, per step
};

}  // namespace

void OnlineExperimentConfig::validate() const {
  base.validate();
  online.validate();
  if (base.perceive) {
    throw InvalidInputError("online experiment: perception is not part of the online mission yet");
  }
  if (online.robust) {
    throw InvalidInputError(
        "online experiment: set base.robust (with base.gnc_threshold and "
        "base.retest_left_out), not online.robust, which the run builds from "
        "them as the batch experiment builds its robust solve");
  }
  if (base.information != InformationMode::kNoise) {
    throw InvalidInputError(
        "online experiment: the robots solve with the information of their "
        "measurements (information mode 'noise')");
  }
  if (base.robots < 2) {
    throw InvalidInputError("online experiment: a team is two robots or more");
  }
}

OnlineRunMetrics RunOnlineSimulationOnce(const OnlineExperimentConfig& config, int run) {
  config.validate();
  const auto t0 = Clock::now();
  OnlineRunMetrics m = OnlineMission(config, run).measure();
  m.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  return m;
}

OnlineExperimentResult RunOnlineExperiment(const OnlineExperimentConfig& config) {
  config.validate();
  OnlineExperimentResult out;
  out.config = config;
  for (int i = 0; i < config.base.runs; ++i) out.runs.push_back(RunOnlineSimulationOnce(config, i));
  return out;
}

namespace {

// Every robot of every run of a result: its final ATE online, of the batch optimum, of the
// outlier-free batch and solo, and the ratio online / reference.
struct RobotsAtTheEnd {
  std::vector<double> online, batch, free, solo, ratios;
  int within = 0;  // ratios <= 1.1
  double worst() const {
    return ratios.empty() ? 0.0 : *std::max_element(ratios.begin(), ratios.end());
  }
};
RobotsAtTheEnd CollectRobots(const OnlineExperimentResult& r, bool against_free) {
  RobotsAtTheEnd out;
  for (const OnlineRunMetrics& m : r.runs) {
    for (std::size_t i = 0; i < m.online_ate.size(); ++i) {
      out.online.push_back(m.online_ate[i]);
      out.batch.push_back(m.batch_ate[i]);
      out.free.push_back(m.free_ate[i]);
      out.solo.push_back(m.solo_ate[i]);
      // NaN without an outlier-free reference: never within.
      out.ratios.push_back(m.online_ate[i] / (against_free ? m.free_ate[i] : m.batch_ate[i]));
      out.within += out.ratios.back() <= 1.1 ? 1 : 0;
    }
  }
  return out;
}

}  // namespace

std::string FormatOnlineTable(const std::vector<OnlineExperimentResult>& results) {
  std::string s =
      "| scenario | robots | runs | rendezvous / run | solves / run | final ATE online (m) | "
      "batch optimum (m) | solo (m) | online / batch: median robot | worst robot | robots "
      "within 1.1x | kB per solve: objects | DGS | point clouds |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const OnlineExperimentResult& r : results) {
    const RobotsAtTheEnd e = CollectRobots(r, false);
    double rendezvous = 0, solves = 0, objects = 0, dgs = 0, pcd = 0, points = 0;
    for (const OnlineRunMetrics& m : r.runs) {
      rendezvous += m.rendezvous;
      solves += m.solves;
      for (const OnlineRendezvousPoint& p : m.points) {
        objects += p.bytes_objects;
        dgs += p.bytes_dgs;
        pcd += p.bytes_point_clouds;
        points += 1;
      }
    }
    const double runs = static_cast<double>(r.runs.size());
    s += fmt::format(
        "| {} | {} | {} | {:.1f} | {:.1f} | {:.3f} | {:.3f} | {:.3f} | {:.3f} | {:.3f} | {} of {} "
        "| {:.2f} | {:.1f} | {:.0f} |\n",
        r.config.base.scenario, r.config.base.robots, r.runs.size(), rendezvous / runs,
        solves / runs, Mean(e.online), Mean(e.batch), Mean(e.solo), Median(e.ratios), e.worst(),
        e.within, e.ratios.size(), objects / points / 1e3, dgs / points / 1e3,
        pcd / points / 1e3);
  }
  return s;
}

std::string FormatOnlineRobustTable(const std::vector<OnlineExperimentResult>& results) {
  std::string s =
      "| scenario | robots | P | group solves | runs | pairs / run: wrong (injected) | set aside "
      "/ run: wrong | outlier precision / recall | wrong observations / run | observations set "
      "aside / run: wrong | unlinked solves / run | final ATE online (m) | batch of the kept "
      "pairs (m) | outlier-free batch (m) | solo (m) | online / outlier-free: median robot | "
      "worst robot | robots within 1.1x | robust extra kB / run |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const OnlineExperimentResult& r : results) {
    const RobotsAtTheEnd e = CollectRobots(r, true);
    double pairs = 0, wrong = 0, injected = 0, aside = 0, aside_wrong = 0, unlinked = 0, extra = 0;
    double obs_wrong = 0, obs_aside = 0, obs_aside_wrong = 0;
    for (const OnlineRunMetrics& m : r.runs) {
      pairs += m.pairs;
      wrong += m.wrong_pairs;
      injected += m.injected;
      aside += m.set_aside;
      aside_wrong += m.set_aside_wrong;
      unlinked += m.unlinked_solves;
      extra += m.robust_extra_bytes;
      obs_wrong += m.wrong_observations;
      obs_aside += m.observations_set_aside;
      obs_aside_wrong += m.observations_set_aside_wrong;
    }
    const double runs = static_cast<double>(r.runs.size());
    const ExperimentConfig& c = r.config.base;
    s += fmt::format(
        "| {} | {} | {} | {} | {} | {:.1f}: {:.1f} ({:.1f}) | {:.1f}: {:.1f} | {:.3f} / {:.3f} | "
        "{:.1f} | {:.1f}: {:.1f} | {:.1f} | {:.3f} | {:.3f} | {:.3f} | {:.3f} | {:.3f} | {:.3f} | "
        "{} of {} | {:.1f} |\n",
        c.scenario, c.robots, c.outlier_fraction, c.robust ? "robust" : "least squares",
        r.runs.size(), pairs / runs, wrong / runs, injected / runs, aside / runs,
        aside_wrong / runs, aside > 0 ? aside_wrong / aside : 1.0,
        wrong > 0 ? aside_wrong / wrong : 1.0, obs_wrong / runs, obs_aside / runs,
        obs_aside_wrong / runs, unlinked / runs, Mean(e.online), Mean(e.batch), Mean(e.free),
        Mean(e.solo), Median(e.ratios), e.worst(), e.within, e.ratios.size(),
        extra / runs / 1e3);
  }
  return s;
}

std::string OnlineResultsToJson(const std::vector<OnlineExperimentResult>& results) {
  nlohmann::json rows = nlohmann::json::array();
  for (const OnlineExperimentResult& r : results) {
    nlohmann::json runs = nlohmann::json::array();
    for (const OnlineRunMetrics& m : r.runs) {
      nlohmann::json points = nlohmann::json::array();
      for (const OnlineRendezvousPoint& p : m.points) {
        points.push_back({{"step", p.step}, {"robots", p.robots}, {"team_ate", p.team_ate},
                          {"solo_ate", p.solo_ate}, {"robots_measured", p.robots_measured},
                          {"rotation_sweeps", p.rotation_sweeps}, {"pose_sweeps", p.pose_sweeps},
                          {"refine_steps", p.refine_steps}, {"object_object", p.object_object},
                          {"team_factors", p.team_factors}, {"bytes_objects", p.bytes_objects},
                          {"bytes_dgs", p.bytes_dgs},
                          {"bytes_point_clouds", p.bytes_point_clouds}, {"seconds", p.seconds}});
      }
      runs.push_back({{"seed", m.seed}, {"online_ate", m.online_ate}, {"batch_ate", m.batch_ate},
                      {"solo_ate", m.solo_ate}, {"online_are", m.online_are},
                      {"batch_are", m.batch_are}, {"worst_ratio", m.worst_ratio},
                      {"free_ate", m.free_ate}, {"pairs", m.pairs}, {"wrong_pairs", m.wrong_pairs},
                      {"injected", m.injected}, {"set_aside", m.set_aside},
                      {"set_aside_wrong", m.set_aside_wrong},
                      {"unlinked_solves", m.unlinked_solves},
                      {"wrong_observations", m.wrong_observations},
                      {"observations_set_aside", m.observations_set_aside},
                      {"observations_set_aside_wrong", m.observations_set_aside_wrong},
                      {"robust_extra_bytes", m.robust_extra_bytes},
                      {"rendezvous", m.rendezvous}, {"solves", m.solves},
                      {"bytes_objects", m.bytes_objects}, {"bytes_dgs", m.bytes_dgs},
                      {"seconds", m.seconds}, {"points", std::move(points)}});
    }
    const ExperimentConfig& c = r.config.base;
    const DgsOptions& o = r.config.online.solver;
    rows.push_back({{"config",
                     {{"scenario", c.scenario}, {"robots", c.robots}, {"runs", c.runs},
                      {"seed", c.seed}, {"poses_per_robot", c.poses_per_robot},
                      {"sigma_rotation_deg", c.sigma_rotation_deg},
                      {"sigma_translation", c.sigma_translation},
                      {"known_initial_poses", c.known_initial_poses},
                      {"outlier_fraction", c.outlier_fraction}, {"robust", c.robust},
                      {"order", ToString(o.order)}, {"two_level", o.coarse_correction},
                      {"stop", ToString(o.stopping)}, {"refine", o.refine},
                      {"eta_rotation", o.eta_rotation}, {"eta_pose", o.eta_pose}}},
                    {"runs", std::move(runs)}});
  }
  return nlohmann::json{{"rows", std::move(rows)}}.dump();
}

std::string PlotOnlineSvg(const OnlineExperimentResult& result, const std::string& title) {
  double max_step = 1.0, max_ate = 1e-3;
  std::vector<double> batch;
  for (const OnlineRunMetrics& m : result.runs) {
    for (const OnlineRendezvousPoint& p : m.points) {
      max_step = std::max(max_step, static_cast<double>(p.step));
      for (double v : {p.team_ate, p.solo_ate}) {
        if (std::isfinite(v)) max_ate = std::max(max_ate, v);
      }
    }
    batch.push_back(Mean(m.batch_ate));
  }
  max_step = std::max(max_step, static_cast<double>(result.config.base.poses_per_robot));
  const double left = 60, right = 20, top = 66, bottom = 45, width = 720, height = 400;
  const double plot_w = width - left - right, plot_h = height - top - bottom;
  const auto px = [&](double step) { return left + step / max_step * plot_w; };
  const auto py = [&](double ate) { return top + plot_h - ate / (1.05 * max_ate) * plot_h; };
  std::string svg = fmt::format(
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" "
      "width=\"{0:.0f}\" height=\"{1:.0f}\" viewBox=\"0 0 {0:.0f} {1:.0f}\">\n"
      "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
      "<text x=\"{2:.0f}\" y=\"18\" font-family=\"sans-serif\" font-size=\"14\">{3}</text>\n"
      "<text x=\"{2:.0f}\" y=\"34\" font-family=\"sans-serif\" font-size=\"11\">team map error "
      "after each rendezvous: mean over the robots of each map's ATE (m), one colour per run"
      "</text>\n<text x=\"{2:.0f}\" y=\"49\" font-family=\"sans-serif\" font-size=\"11\">"
      "solid: online; dashed: solo SLAM; grey line: batch optimum at the end (mean of runs)"
      "</text>\n",
      width, height, left, title);
  // Axes and ticks.
  svg += fmt::format("<line x1=\"{0:.1f}\" y1=\"{1:.1f}\" x2=\"{0:.1f}\" y2=\"{2:.1f}\" "
                     "stroke=\"black\"/>\n<line x1=\"{0:.1f}\" y1=\"{2:.1f}\" x2=\"{3:.1f}\" "
                     "y2=\"{2:.1f}\" stroke=\"black\"/>\n",
                     left, top, top + plot_h, left + plot_w);
  for (int i = 0; i <= 5; ++i) {
    const double a = 1.05 * max_ate * i / 5.0, st = max_step * i / 5.0;
    svg += fmt::format(
        "<text x=\"{:.1f}\" y=\"{:.1f}\" font-family=\"sans-serif\" font-size=\"10\" "
        "text-anchor=\"end\">{:.2f}</text>\n<text x=\"{:.1f}\" y=\"{:.1f}\" "
        "font-family=\"sans-serif\" font-size=\"10\" text-anchor=\"middle\">{:.0f}</text>\n",
        left - 4, py(a) + 3, a, px(st), top + plot_h + 14, st);
  }
  svg += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" font-family=\"sans-serif\" font-size=\"11\" "
                     "text-anchor=\"middle\">time step</text>\n",
                     left + plot_w / 2, height - 8);
  static const char* kColours[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                                   "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};
  for (std::size_t run = 0; run < result.runs.size(); ++run) {
    const char* colour = kColours[run % 10];
    for (int pass = 0; pass < 2; ++pass) {
      std::string points;
      int last_step = -1;
      for (const OnlineRendezvousPoint& p : result.runs[run].points) {
        const double v = pass == 0 ? p.team_ate : p.solo_ate;
        if (!std::isfinite(v) || p.step == last_step) continue;
        last_step = p.step;
        points += fmt::format("{:.1f},{:.1f} ", px(p.step), py(v));
      }
      svg += fmt::format("<polyline fill=\"none\" stroke=\"{}\" stroke-width=\"1.2\"{} "
                         "points=\"{}\"/>\n",
                         colour, pass == 0 ? "" : " stroke-dasharray=\"4,3\"", points);
    }
  }
  const double b = Mean(batch);
  if (std::isfinite(b)) {
    svg += fmt::format("<line x1=\"{:.1f}\" y1=\"{:.1f}\" x2=\"{:.1f}\" y2=\"{:.1f}\" "
                       "stroke=\"#999\" stroke-width=\"2\"/>\n",
                       left, py(b), left + plot_w, py(b));
  }
  svg += "</svg>\n";
  return svg;
}

}  // namespace moslam
