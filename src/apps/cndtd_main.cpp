// cndtd: the consensus-NDT LiDAR SLAM daemon. Wiring only: the runtime library does the work.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <iostream>
#include <sstream>

#include "cndt/config/config.hpp"
#include "cndt/core/exit_codes.hpp"
#include "cndt/runtime/daemon.hpp"

int main(int argc, char** argv) {
  auto logger = spdlog::stderr_color_mt("cndtd");
  logger->set_pattern("cndtd: %^%l%$: %v");
  spdlog::set_default_logger(logger);

  CLI::App app{
      "cndtd: consensus-NDT LiDAR SLAM daemon. Reads VLP-16 packets (UDP, or a capture), "
      "publishes every scan's pose with its consensus metric Cm on CAN (config/cndt.dbc) and "
      "UDP (docs/protocol.md), and optionally builds and saves a map. Runs under systemd as "
      "Type=notify (systemd/cndtd.service). Exit codes: 0 ok, 2 usage, 65 bad input data (a "
      "damaged map), 66 missing input, 74 I/O error, 78 bad configuration"};
  app.set_version_flag("--version", "cndtd 0.1.0");
  std::string config_path;
  bool check = false, print = false;
  app.add_option("-c,--config", config_path,
                 "Configuration file (TOML; config/cndtd.toml documents every key)");
  app.add_flag("--check", check,
               "Check the configuration, print every problem with its line, and exit (0 valid, "
               "78 invalid)");
  app.add_flag("--print-config", print,
               "Print the documented default configuration (config/cndtd.toml) and exit");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? 0 : cndt::core::kExitUsage;
  }
  if (print) {
    std::cout << cndt::config::documented_defaults();
    return cndt::core::kExitOk;
  }
  if (config_path.empty()) {
    spdlog::error("no configuration: give --config FILE (config/cndtd.toml documents every key)");
    return cndt::core::kExitUsage;
  }
  auto config = cndt::config::load_config(config_path);
  if (!config) {
    std::istringstream lines(config.error().message);
    for (std::string line; std::getline(lines, line);) spdlog::error("{}", line);
    return config.error().code;
  }
  if (check) {
    spdlog::info("'{}' is valid", config_path);
    return cndt::core::kExitOk;
  }
  spdlog::set_level(spdlog::level::from_str(config.value().log.level));
  spdlog::info("cndtd 0.1.0 starting with '{}'; effective configuration:", config_path);
  std::istringstream eff(cndt::config::effective(config.value()));
  for (std::string line; std::getline(eff, line);) spdlog::info("  {}", line);
  return cndt::runtime::run_daemon(config.value());
}
