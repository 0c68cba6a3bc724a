// cndt sweep: the paper's Figure 9 experiment on a capture. The odometry runs up to one scan;
// that scan's reference is held, and its pose is moved away from the estimate along chosen axes
// while Cm (eqs 10-13) is measured at each step.
#include "cndt/slam/sweep.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <numbers>
#include <string_view>

#include "cndt/cli/commands.hpp"
#include "cndt/runtime/setup.hpp"

namespace cndt::cli {
namespace {

struct AxisName {
  std::string_view name;
  int index;  // in core::Pose6: x y z roll pitch yaw
};
constexpr std::array<AxisName, 6> kAxes{
    {{"x", 0}, {"y", 1}, {"z", 2}, {"roll", 3}, {"pitch", 4}, {"yaw", 5}}};

bool is_rotation(int axis) { return axis >= 3; }

struct AxisSweep {
  std::string name;
  int axis = 0;
  std::vector<double> shown;  // perturbations in the unit shown (m or deg)
  std::vector<slam::SweepSample> samples;
  double spearman = 0.0;
  [[nodiscard]] const char* unit() const { return is_rotation(axis) ? "deg" : "m"; }
};

// An SVG chart per axis, side by side: Cm (0 to 1) against the perturbation.
std::string svg_plot(const std::vector<AxisSweep>& sweeps, std::size_t scan) {
  constexpr double kW = 360, kH = 270, kLeft = 52, kRight = 16, kTop = 36, kBottom = 46;
  const double pw = kW - kLeft - kRight, ph = kH - kTop - kBottom;
  std::string s = fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{:.0f}\" height=\"{:.0f}\" "
      "font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" "
      "fill=\"white\"/>\n",
      kW * static_cast<double>(sweeps.size()), kH);
  for (std::size_t k = 0; k < sweeps.size(); ++k) {
    const AxisSweep& a = sweeps[k];
    const double ox = kW * static_cast<double>(k) + kLeft;
    const double max = std::max(a.shown.back(), 1e-12);
    const auto px = [&](double v) { return ox + pw * v / max; };
    const auto py = [&](double cm) { return kTop + ph * (1.0 - std::clamp(cm, 0.0, 1.0)); };
    s += fmt::format(
        "<text x=\"{:.1f}\" y=\"20\" text-anchor=\"middle\">scan {}: Cm against {} "
        "(Spearman {:.3f})</text>\n",
        ox + pw / 2, scan, a.name, a.spearman);
    s += fmt::format(
        "<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" fill=\"none\" "
        "stroke=\"black\"/>\n",
        ox, kTop, pw, ph);
    for (int i = 0; i <= 4; ++i) {
      const double cm = 0.25 * i, v = max * 0.25 * i;
      s += fmt::format(
          "<line x1=\"{0:.1f}\" y1=\"{1:.1f}\" x2=\"{2:.1f}\" y2=\"{1:.1f}\" stroke=\"#ddd\"/>"
          "<text x=\"{3:.1f}\" y=\"{4:.1f}\" text-anchor=\"end\">{5:.2f}</text>\n",
          ox, py(cm), ox + pw, ox - 6, py(cm) + 4, cm);
      s += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\">{:.3g}</text>\n",
                       px(v), kTop + ph + 16, v);
    }
    s += fmt::format(
        "<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\">{} perturbation, {}</text>\n",
        ox + pw / 2, kH - 8, a.name, a.unit());
    s += fmt::format(
        "<text x=\"{0:.1f}\" y=\"{1:.1f}\" text-anchor=\"middle\" "
        "transform=\"rotate(-90 {0:.1f} {1:.1f})\">Cm</text>\n",
        ox - 38, kTop + ph / 2);
    std::string points;
    for (std::size_t i = 0; i < a.samples.size(); ++i) {
      points += fmt::format("{}{:.1f},{:.1f}", points.empty() ? "" : " ", px(a.shown[i]),
                            py(a.samples[i].cm));
    }
    s += fmt::format(
        "<polyline points=\"{}\" fill=\"none\" stroke=\"#1f5fa8\" stroke-width=\"2\"/>\n", points);
    for (std::size_t i = 0; i < a.samples.size(); ++i) {
      s += fmt::format("<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"2.5\" fill=\"#1f5fa8\"/>\n",
                       px(a.shown[i]), py(a.samples[i].cm));
    }
  }
  s += "</svg>\n";
  return s;
}

// The odometry up to scan `target`, which is estimated and held (not committed).
struct Run {
  slam::ConsensusOdometry* odometry;
  std::size_t target, seen = 0;
  slam::OdometryResult result;
};

}  // namespace

void register_sweep(CLI::App& app, SweepArgs& a) {
  auto* cmd = a.command = app.add_subcommand(
      "sweep",
      "The paper's Figure 9 experiment: run the odometry over a capture up to one scan, hold "
      "the reference that scan was matched against, move the scan away from its estimated pose "
      "step by step along each axis asked for, and measure the localization consensus Cm "
      "(eqs 10-13) at every step. Writes sweep.csv (axis, perturbation, unit, Cm, voxels with "
      "a Cv) and sweep.svg (Cm against the perturbation, one chart per axis), and prints JSON: "
      "the scan's stamp and reported Cm and, per axis, Cm at 0 and at the largest step and "
      "the Spearman rank correlation of Cm with the perturbation");
  add_odometry_input_options(*cmd, a.input);
  cmd->add_option("--out", a.out_dir, "Output folder (created if missing)")->required();
  cmd->add_option("--scan", a.scan,
                  "Which scan: its 0-based row in replay's scans.csv (the first revolution, "
                  "often partial, is row 0). It must have been matched against a reference")
      ->capture_default_str();
  std::vector<std::string> axis_names;
  for (const AxisName& n : kAxes) axis_names.emplace_back(n.name);
  cmd->add_option("--axes", a.axes,
                  "Axes to move the scan along, comma-separated: x y z (metres, along the "
                  "odometry frame's axes) roll pitch yaw (degrees, added to the pose's angles "
                  "of R = Rx(roll) Ry(pitch) Rz(yaw))")
      ->delimiter(',')
      ->capture_default_str()
      ->check(CLI::IsMember(axis_names));
  cmd->add_option("--max-translation", a.max_translation_m,
                  "Largest move along x, y and z, metres (paper: 2)")
      ->capture_default_str()
      ->check(CLI::Range(0.001, 100.0));
  cmd->add_option("--max-rotation", a.max_rotation_deg,
                  "Largest turn about roll, pitch and yaw, degrees (paper: 5)")
      ->capture_default_str()
      ->check(CLI::Range(0.001, 180.0));
  cmd->add_option("--steps", a.steps, "Steps from 0 to the largest move (steps + 1 samples)")
      ->capture_default_str()
      ->check(CLI::Range(2, 1000));
}

int run_sweep(const SweepArgs& a) {
  auto loaded = odometry_config(a.input, a.command);
  if (!loaded) return fail(loaded.error());
  const config::Config& c = loaded.value();
  if (auto err = check_not_one_cloud(a.input.capture)) return fail(*err);
  std::vector<AxisSweep> sweeps;
  for (const std::string& name : a.axes) {
    const auto* it =
        std::find_if(kAxes.begin(), kAxes.end(), [&](const AxisName& n) { return n.name == name; });
    if (it == kAxes.end()) {
      return fail({core::kExitUsage,
                   fmt::format("--axes: '{}' is not one of x, y, z, roll, pitch, yaw", name)});
    }
    AxisSweep s;
    s.name = name;
    s.axis = it->index;
    sweeps.push_back(std::move(s));
  }
  if (sweeps.empty()) return fail({core::kExitUsage, "--axes: no axis given"});
  auto setup = runtime::make_setup(c);
  if (!setup) return fail(setup.error());
  if (auto err = create_output_dir(a.out_dir)) return fail(*err);

  auto odometry = std::make_unique<slam::ConsensusOdometry>(setup.value().pipeline.odometry);
  Run run{odometry.get(), a.scan, 0, {}};
  const auto visit = [](const core::Scan& scan, void* ctx) {
    auto& r = *static_cast<Run*>(ctx);
    if (r.seen++ < r.target) {
      r.odometry->process(scan);
      return;
    }
    r.result = r.odometry->estimate(scan);
  };
  CaptureOptions co;
  co.pcap = setup.value().pcap;
  co.driver = setup.value().driver;
  auto report = read_scans(a.input.capture, co, setup.value().max_points, a.input.scan_period_s,
                           a.scan + 1, visit, &run);
  if (!report) return fail(report.error());
  warn_if_cut_short(report.value());
  if (run.seen == 0) return fail(no_scan_error(a.input.capture, report.value().driver));
  if (run.seen <= a.scan) {
    return fail(
        {core::kExitDataError, fmt::format("'{}' has {} scans: --scan {} must be below that",
                                           a.input.capture, run.seen, a.scan)});
  }
  const slam::OdometryResult& r = run.result;
  if ((r.flags & slam::kOdomSkipped) != 0) {
    return fail({core::kExitDataError,
                 fmt::format("scan {} of '{}' was skipped (flags {}: a partial revolution) and "
                             "has no pose to move; choose a later one",
                             a.scan, a.input.capture, r.flags)});
  }
  const bool first = (r.flags & slam::kOdomFirstScan) != 0;
  if (first || (r.flags & slam::kOdomTooFewPoints) != 0) {
    return fail({core::kExitDataError,
                 fmt::format("scan {} of '{}' was not matched (flags {}: {}); choose a later one",
                             a.scan, a.input.capture, r.flags,
                             first ? "the first, with no reference yet" : "too few points")});
  }

  for (AxisSweep& s : sweeps) {
    const double max = is_rotation(s.axis) ? a.max_rotation_deg : a.max_translation_m;
    const double to_pose = is_rotation(s.axis) ? std::numbers::pi / 180.0 : 1.0;
    std::vector<double> values;
    for (int i = 0; i <= a.steps; ++i) {
      s.shown.push_back(max * i / a.steps);
      values.push_back(s.shown.back() * to_pose);
    }
    s.samples = slam::sweep_cm(*odometry, r, s.axis, values);
    std::vector<double> cms;
    for (const auto& sample : s.samples) cms.push_back(sample.cm);
    s.spearman = slam::spearman(values, cms);
  }

  const std::filesystem::path dir(a.out_dir);
  std::ofstream csv(dir / "sweep.csv", std::ios::trunc);
  std::ofstream svg(dir / "sweep.svg", std::ios::trunc);
  if (!csv || !svg) {
    return fail({core::kExitIoError,
                 fmt::format("cannot write in '{}': {}", a.out_dir, std::strerror(errno))});
  }
  csv << "axis,perturbation,unit,cm,voxels_with_cv\n";
  for (const AxisSweep& s : sweeps) {
    for (std::size_t i = 0; i < s.samples.size(); ++i) {
      csv << fmt::format("{},{:.6f},{},{:.6f},{}\n", s.name, s.shown[i], s.unit(), s.samples[i].cm,
                         s.samples[i].voxels);
    }
  }
  svg << svg_plot(sweeps, a.scan);
  csv.close();
  svg.close();
  if (!csv || !svg) {
    return fail({core::kExitIoError, fmt::format("writing in '{}' failed", a.out_dir)});
  }

  const std::int64_t ns = r.stamp.count();
  std::string axes;
  for (const AxisSweep& s : sweeps) {
    axes += fmt::format(
        "{}\n    {{\"axis\": \"{}\", \"unit\": \"{}\", \"max\": {:.6f}, \"cm_at_zero\": {:.6f}, "
        "\"cm_at_max\": {:.6f}, \"voxels_with_cv_at_zero\": {}, \"spearman\": {:.6f}}}",
        axes.empty() ? "" : ",", s.name, s.unit(), s.shown.back(), s.samples.front().cm,
        s.samples.back().cm, s.samples.front().voxels, s.spearman);
    spdlog::info("{}: Cm {:.3f} at 0, {:.3f} at {:g} {}; Spearman rank correlation {:.3f}", s.name,
                 s.samples.front().cm, s.samples.back().cm, s.shown.back(), s.unit(), s.spearman);
  }
  std::cout << fmt::format(
      "{{\n  \"scan\": {},\n  \"stamp\": {}.{:09d},\n  \"cm_reported\": {:.6f},\n  \"flags\": "
      "{},\n  \"reference_voxels\": {},\n  \"points\": {},\n  \"axes\": [{}\n  ]\n}}\n",
      a.scan, ns / 1'000'000'000, ns % 1'000'000'000, r.cm, r.flags,
      odometry->reference_grid().size(), odometry->scan_points().size(), axes);
  spdlog::info("sweep.csv and sweep.svg in '{}'", a.out_dir);
  return core::kExitOk;
}

}  // namespace cndt::cli
