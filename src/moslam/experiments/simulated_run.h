// The simulation of one run of an experiment and the SLAM config it is mapped with, shared by
// the batch experiment (simulation_experiment.h) and the online one (online_experiment.h), so
// the same config and run give the same data in both.
#pragma once

#include <map>
#include <vector>

#include "moslam/experiments/simulation_experiment.h"
#include "moslam/sim/sensing.h"
#include "moslam/slam/multi_robot.h"

namespace moslam {

struct SimulatedRun {
  unsigned seed = 0;  // config.seed + run
  SimulationData data;
  MultiRobotSlamConfig slam;
};

// Validates `config`; runs config.perceive (filling `metrics`) when set.
SimulatedRun SimulateRun(const ExperimentConfig& config, int run, RunMetrics& metrics);

// The world object each landmark of `robots` stands for: the one most of its observations in
// `joint` (AssembleJointProblem of these robots) are of (ties: the one that created it; -1: a
// false detection's). A wrong association inside a map can outnumber the right ones.
std::map<Key, int> LandmarkObjects(const JointProblem& joint, const std::vector<ObjectSlam>& robots);

// Whether a shared pair joins landmarks of two different world objects (LandmarkObjects).
bool WrongPair(const std::map<Key, int>& objects, const Key& a, const Key& b);

}  // namespace moslam
