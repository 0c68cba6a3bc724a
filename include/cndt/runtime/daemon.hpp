// cndtd: the input (UDP from the sensor, or a capture), the pipeline, the publishers, health
// lines and the systemd protocol (READY=1 once scans flow, WATCHDOG=1 from the odometry loop,
// STATUS= lines), and a clean stop on SIGTERM/SIGINT: the scan in hand is finished, outputs are
// flushed, the map is saved atomically, exit 0.
#pragma once

#include "cndt/config/config.hpp"

namespace cndt::runtime {

/// Runs until a stop signal (or the end of a capture source); returns the exit code.
int run_daemon(const config::Config& config);

}  // namespace cndt::runtime
