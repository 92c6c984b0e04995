// The simulation of one run of an experiment and the SLAM config it is mapped with, shared by
// the batch experiment (simulation_experiment.h) and the online one (online_experiment.h), so
// the same config and run give the same data in both.
#pragma once

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

}  // namespace moslam
