// cndt: the command-line tool. Wiring only: every subcommand lives in the cndt_cli library.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>

#include "cndt/cli/commands.hpp"
#include "cndt/core/exit_codes.hpp"

int main(int argc, char** argv) {
  auto logger = spdlog::stderr_color_mt("cndt");
  logger->set_pattern("cndt: %^%l%$: %v");
  spdlog::set_default_logger(logger);

  CLI::App app{"cndt: consensus-NDT LiDAR tools for Velodyne VLP-16 captures"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "cndt 0.1.0");
  bool verbose = false;
  app.add_flag("-v,--verbose", verbose, "Log debug messages");

  cndt::cli::InfoArgs info;
  cndt::cli::DecodeArgs decode;
  cndt::cli::SimArgs sim;
  cndt::cli::RecordArgs record;
  cndt::cli::ReplayArgs replay;
  cndt::cli::EvalArgs eval;
  cndt::cli::SweepArgs sweep;
  cndt::cli::MapArgs map;
  cndt::cli::ListenArgs listen;
  cndt::cli::register_info(app, info);
  cndt::cli::register_decode(app, decode);
  cndt::cli::register_sim(app, sim);
  cndt::cli::register_record(app, record);
  cndt::cli::register_replay(app, replay);
  cndt::cli::register_eval(app, eval);
  cndt::cli::register_sweep(app, sweep);
  cndt::cli::register_map(app, map);
  cndt::cli::register_listen(app, listen);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? 0 : cndt::core::kExitUsage;
  }
  if (verbose) spdlog::set_level(spdlog::level::debug);
  if (app.got_subcommand("info")) return cndt::cli::run_info(info);
  if (app.got_subcommand("decode")) return cndt::cli::run_decode(decode);
  if (app.got_subcommand("sim")) return cndt::cli::run_sim(sim);
  if (app.got_subcommand("record")) return cndt::cli::run_record(record);
  if (app.got_subcommand("replay")) return cndt::cli::run_replay(replay);
  if (app.got_subcommand("eval")) return cndt::cli::run_eval(eval);
  if (app.got_subcommand("sweep")) return cndt::cli::run_sweep(sweep);
  if (app.got_subcommand("map")) return cndt::cli::run_map(map);
  if (app.got_subcommand("listen")) return cndt::cli::run_listen(listen);
  return cndt::core::kExitUsage;
}
