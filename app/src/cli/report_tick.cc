// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tick time per scene type: the compute time of HapticLoop::Step (calibration, FK, the scene's
// force fields, safety, tension solve) on the simulated SPIDAR-G gripped by the simulated hand,
// as in `spidarcad run`, over N ticks (the trajectory repeats); and the report section that
// shows their distributions.
// Scenes: empty; demo (plane wall + spring); implicit proxy (assets/scenes/platform.json, two
// ProxyFields, press onto the plate); six-DOF shell tool (platform.json, cross-grip point shell
// against the union of both solids, twist against the wall; once with the grip's 196 points and
// once with 2004); FE contact (platform.json meshed
// at 12 mm, FeTouchField on the steel part, the hand driving the tool sphere into the plate;
// one row over every tick, one over the ticks where the field holds k = 16 contact nodes, and
// the k reached is printed; see MeasureFe); sculpt (assets/scenes/clay.json meshed at 3 mm,
// SculptToolField during a grab stroke the closed grip drags up and down; the main-thread stroke
// update, SculptSession::Step, runs every 16th tick outside the timing, as the window does at
// 60 Hz); sculpt pinch (the same clay squeezed between the fingertips: the clay width, see
// MeasureClayPinch); assembly (assets/scenes/assembly.json, the AssemblyField of the toy robot,
// X_WD identity, the device calibrated at start-up as the window does, the hand following
// assets/trajectories/seat_right_leg.csv: grasp, carry, seat the right leg; one row over every
// tick, one over the ticks while a part is carried).
#include "cli/report_tick.h"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <functional>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include "cli/golden_runs.h"
#include "cli/report_common.h"
#include "cli/report_sections.h"
#include "doc/assets.h"
#include "scene/assembly_scene.h"
#include "scene/device_rig.h"
#include "scene/fe_model.h"
#include "scene/fe_touch_field.h"
#include "scene/scene_haptics.h"
#include "scene/scene_solid.h"
#include "scene/scripted_run.h"
#include "scene/sculpt_field.h"
#include "spidarcad/haptics/haptic_loop.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/realtime_memory.h"
#include "spidarcad/haptics/simulated_device.h"
#include "spidarcad/haptics/simulated_hand.h"
#include "spidarcad/haptics/trajectory.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::app {

namespace {

using Row = SceneTickRow;

std::string AssetDir() { return AssetPath("") + "/"; }

// Called after each tick with its index and outputs, outside the timed region (main-thread
// work such as the sculpt session's stroke update).
using AfterTick = std::function<void(long, const haptics::TickOutputs&)>;

// CPU time of the calling thread, µs (not advanced while the thread is preempted).
double ThreadCpuMicros() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e6 + ts.tv_nsec * 1e-3;
}

// Faults and context switches of the calling thread so far.
TickCounters ThreadCounters() {
  rusage ru{};
  getrusage(RUSAGE_THREAD, &ru);
  TickCounters c;
  c.minor_faults = static_cast<std::uint32_t>(ru.ru_minflt);
  c.major_faults = static_cast<std::uint32_t>(ru.ru_majflt);
  c.voluntary_switches = static_cast<std::uint32_t>(ru.ru_nvcsw);
  c.involuntary_switches = static_cast<std::uint32_t>(ru.ru_nivcsw);
  return c;
}

// after − before, counter by counter.
TickCounters Difference(const TickCounters& after, const TickCounters& before) {
  TickCounters d;
  d.minor_faults = after.minor_faults - before.minor_faults;
  d.major_faults = after.major_faults - before.major_faults;
  d.voluntary_switches = after.voluntary_switches - before.voluntary_switches;
  d.involuntary_switches = after.involuntary_switches - before.involuntary_switches;
  return d;
}

// Runs `body` on the measuring thread (SceneTickOptions::realtime) and returns its scheduling.
std::string OnMeasuringThread(bool realtime, const std::function<void()>& body) {
  std::string scheduling = "normal scheduling";
  if (realtime) {
    // A thread of its own, made from this (normal) thread, that raises its own priority: the
    // threads the scene made before (the FE column worker) stay normal, as in the window.
    std::thread thread([&] {
      sched_param param{};
      param.sched_priority = 80;
      const int err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
      scheduling = err == 0 ? "SCHED_FIFO 80"
                            : std::string("normal scheduling (SCHED_FIFO refused: ") +
                                  std::strerror(err) + ")";
      body();
    });
    thread.join();
  } else {
    body();
  }
  return scheduling;
}

Row Measure(const std::string& name, std::unique_ptr<haptics::HapticScene> scene,
            const haptics::LoopSettings& loop_settings, const haptics::Trajectory& trajectory,
            const SceneTickOptions& options, const AfterTick& after_tick = {},
            const haptics::HandSettings& hand_settings = {}, bool calibrate = false) {
  haptics::SimulatedDeviceConfig config;
  config.seed = 1;
  haptics::SimulatedSpidarG device(config);
  const haptics::DeviceInfo& info = device.info();
  haptics::EncoderCalibration calibration = haptics::EncoderCalibration::Nominal(
      info.encoder, haptics::InverseKinematics(info.geometry, info.home_pose));
  if (calibrate) {  // as the window: the line fit at start-up, then the grip back at the hand
    const SimulatedCalibration fit = CalibrateSimulated(&device);
    if (fit.ok) calibration = fit.calibration;
  }
  haptics::HapticLoop loop(info, calibration, loop_settings);
  loop.Publish(std::move(scene));
  const double dt = 1e-3, t0 = trajectory.start_time();
  const double duration = trajectory.end_time() - t0;
  haptics::SimulatedHand hand(hand_settings, trajectory.Sample(t0), info.geometry.d);
  device.SetTruePose(hand.pose());
  const long ticks = options.ticks, warm_up = std::max(0L, options.warm_up_ticks);
  // Sized (and so touched) here: no first touch of the sample arrays between two readings.
  std::vector<double> us(ticks), cpu(ticks);
  std::vector<TickCounters> counters(ticks);
  // The ticks, on the measuring thread (see SceneTickOptions::realtime).
  auto run_ticks = [&] {
    haptics::PrefaultStack();
    // Ticks j < warm_up are the untimed warm-up; tick j >= warm_up is timed tick k = j − warm_up.
    for (long j = 0; j < warm_up + ticks; ++j) {
      const long k = j - warm_up;
      const double t = t0 + std::fmod(j * dt, duration);
      hand.Step(trajectory.Sample(t), device.TrueWrench(), dt);
      device.SetTruePose(hand.pose());
      device.Step(dt);
      haptics::TickInputs inputs;
      device.Read(&inputs.reading);
      if (k < 0) {
        device.WriteTensions(loop.Step(inputs, dt).tau);
        continue;
      }
      const TickCounters before = ThreadCounters();
      const double cpu_start = ThreadCpuMicros();
      const auto start = std::chrono::steady_clock::now();
      const haptics::TickOutputs out = loop.Step(inputs, dt);
      const auto stop = std::chrono::steady_clock::now();
      const double cpu_stop = ThreadCpuMicros();
      const TickCounters after = ThreadCounters();
      cpu[k] = cpu_stop - cpu_start;
      counters[k] = Difference(after, before);
      device.WriteTensions(out.tau);
      if (after_tick) after_tick(k, out);
      us[k] = std::chrono::duration<double, std::micro>(stop - start).count();
    }
  };
  const std::string scheduling = OnMeasuringThread(options.realtime, run_ticks);
  Row row = SummarizeTicks(name, us, cpu, counters);
  row.scheduling = scheduling;
  return row;
}

haptics::LoopSettings BaseSettings() {
  haptics::LoopSettings s;
  s.fk.max_residual = 5e-3;  // as `spidarcad run`: nominal calibration
  return s;
}

Row MeasureScene(const std::string& name, ToolModel tool, const Eigen::Vector3d& p_WDo,
                 const std::string& trajectory_file, const SceneTickOptions& tick_options,
                 int shell_rings = 12, int shell_around = 8) {
  const modeling::Scene scene = modeling::LoadScene(AssetDir() + "scenes/platform.json");
  SceneHapticsOptions options;
  options.tool = tool;
  options.shell_rings = shell_rings;
  options.shell_around = shell_around;
  options.world_scale = 1.0;
  options.p_WDo = p_WDo;
  SceneHaptics built = BuildHapticScene(scene, options);
  haptics::LoopSettings settings = BaseSettings();
  built.ApplyTo(&settings);
  return Measure(name, std::move(built.scene), settings,
                 haptics::Trajectory::Load(AssetDir() + trajectory_file), tick_options);
}

// Lowers the grip from `above` to `press` over 0.5 s (cosine blend), then holds it there until
// `duration`; grasp angle `grasp` throughout (rad). Device frame.
haptics::Trajectory LowerAndHold(const Eigen::Vector3d& above, const Eigen::Vector3d& press,
                                 double grasp, double duration) {
  haptics::Trajectory trajectory;
  for (int i = 0; i <= 50; ++i) {
    haptics::TrajectorySample s;
    s.t = 0.01 * i;
    s.p_DT = above + (press - above) * 0.5 * (1.0 - std::cos(std::numbers::pi * i / 50.0));
    s.grasp = grasp;
    trajectory.Add(s);
  }
  haptics::TrajectorySample hold;
  hold.t = std::max(duration, 0.6);
  hold.p_DT = press;
  hold.grasp = grasp;
  trajectory.Add(hold);
  return trajectory;
}

// FE contact: the steel platform (12 mm grid, 12.5k linear tets, clamped at the wall) as an
// FeTouchField: tool sphere of 3 mean edges (23 mm), at most 16 contact nodes, felt force scale
// 2e-5, at most 8 N. X_WD: s = 1, p_WDo = (0.1, 0, 0). The hand (default: 300 N/m) lowers the
// grip from 40 mm above onto an aim with the sphere's centre 3 mm below the plate's underside at
// W (0.1, 0.01): the sphere takes in the plate's whole thickness. That is what it takes to load
// 16 nodes: a sphere resting on the plate holds 2 to 5 (the plate bends away and the solve
// releases the rest). The note line gives how often the contact set changed and the mean felt
// force. The columns around the aim are computed before the run. Rows: every tick, and the ticks
// with k = 16.
std::vector<Row> MeasureFe(const SceneTickOptions& options) {
  const long ticks = options.ticks;
  fem::TetMesh mesh = MeshSceneSolidForFe(PlatformScenePath(), "platform", 0.012);
  FeModelSettings model_settings;
  model_settings.use_disk_cache = false;
  std::shared_ptr<FeModel> model = FeModel::Build(std::move(mesh), model_settings);
  FeTouchSettings ts;
  ts.tool_radius = 3.0 * model->mean_edge_length();
  ts.max_contacts = 16;
  ts.force_scale = 2e-5;
  ts.max_force = 8.0;
  auto field = std::make_unique<FeTouchField>(model, ts, nullptr);
  FeTouchField* fe = field.get();
  const Eigen::Vector3d press_W(0.1, 0.01, -0.003);
  const Eigen::Vector3d p_WDo(press_W.x(), 0.0, 0.0);
  haptics::ToolKinematics focus;
  focus.p_WT = press_W;
  fe->Evaluate(focus);  // sets the column focus
  model->cache().Start();
  model->cache().WaitUntilIdle(300.0);
  auto scene = std::make_unique<haptics::HapticScene>();
  scene->Add(std::move(field));
  haptics::LoopSettings settings = BaseSettings();
  settings.X_WD.p_WDo = p_WDo;
  const Eigen::Vector3d press_D = press_W - p_WDo;
  std::vector<int> k_of_tick;
  k_of_tick.reserve(ticks);
  double felt_sum = 0.0;  // felt force magnitude, N (force_scale · FE force, clamped)
  long changes = 0;       // ticks whose contact set differs from the previous tick's
  std::array<int, kMaxFeContacts> previous{};
  int previous_k = 0;
  Row row = Measure(
      "FE contact (platform, k ≤ 16, every tick)", std::move(scene), settings,
      LowerAndHold(press_D + Eigen::Vector3d(0, 0, 0.04), press_D, std::numbers::pi / 2, 30.0),
      options, [&](long, const haptics::TickOutputs&) {
        const FeContactState& st = fe->last_state();
        k_of_tick.push_back(st.num_contacts);
        felt_sum += std::min(ts.max_force, ts.force_scale * st.f_tool_W.norm());
        bool same = st.num_contacts == previous_k;
        for (int i = 0; same && i < st.num_contacts; ++i) same = st.candidate[i] == previous[i];
        changes += !same;
        previous = st.candidate;
        previous_k = st.num_contacts;
      });
  model->cache().Stop();
  long in_contact = 0, k_sum = 0, at_16 = 0;
  std::vector<double> us16, cpu16;
  std::vector<TickCounters> counters16;
  std::vector<long> index16;
  for (std::size_t i = 0; i < k_of_tick.size(); ++i) {
    const int k = k_of_tick[i];
    in_contact += k > 0;
    k_sum += k;
    if (k >= 16) {
      ++at_16;
      us16.push_back(row.us[i]);
      cpu16.push_back(row.cpu[i]);
      counters16.push_back(row.counters[i]);
      index16.push_back(static_cast<long>(i));
    }
  }
  char note[320];
  std::snprintf(
      note, sizeof(note),
      "FE: %d tets, tool radius %.1f mm; k > 0 in %.1f %% of ticks, k = 16 in %.1f %% (%ld ticks), "
      "mean k %.1f; contact set changed in %.1f %% of ticks; mean felt force %.2f N",
      model->mesh().num_elements(), 1e3 * ts.tool_radius, 100.0 * in_contact / ticks,
      100.0 * at_16 / ticks, at_16, static_cast<double>(k_sum) / ticks, 100.0 * changes / ticks,
      felt_sum / ticks);
  row.note = note;
  std::vector<Row> rows{row};
  if (!us16.empty())
    rows.push_back(SummarizeTicks("FE contact (platform, the ticks with k = 16)", us16, cpu16,
                                  counters16, index16));
  return rows;
}

// Sculpt: assets/scenes/clay.json meshed at 3 mm as the clay of a SculptSession; X_WD identity.
// The grip starts just above the clay's top with the grasp closed (40°, below the 70° stroke
// trigger), so the first session step begins a grab stroke; the grip then moves up 15 mm and
// back every 2 s, dragging the clay. The session steps every 16 ticks (outside the timing).
// Loads assets/scenes/clay.json, meshed at 3 mm, as the clay of *session.
void LoadClayJson(SculptSession* session) {
  const SceneSolidGrid grid = PrepareSceneSolid(AssetDir() + "scenes/clay.json", "", 0.003);
  modeling::SurfaceMeshSettings mesh_settings;
  mesh_settings.bounds = grid.bounds;
  mesh_settings.cell_size = grid.cell;
  session->SetMesh(modeling::MeshSurface(grid.compiled, mesh_settings));
}

Row MeasureSculpt(const SceneTickOptions& options) {
  const long ticks = options.ticks;
  SculptSession session;
  LoadClayJson(&session);
  const double grasp = 40.0 * std::numbers::pi / 180.0;
  const Eigen::Vector3d top(0.0, 0.0, 0.062);
  haptics::Trajectory trajectory;
  for (int i = 0; i <= 200; ++i) {
    haptics::TrajectorySample s;
    s.t = 0.01 * i;
    s.p_DT = top + Eigen::Vector3d(0, 0, 0.0075 * (1.0 - std::cos(std::numbers::pi * i / 100.0)));
    s.grasp = grasp;
    trajectory.Add(s);
  }
  auto scene = std::make_unique<haptics::HapticScene>();
  scene->Add(session.MakeField());
  long stroke_ticks = 0, strokes = 0;
  Row row = Measure("sculpt (clay.json, grab stroke)", std::move(scene), BaseSettings(), trajectory,
                    options, [&](long k, const haptics::TickOutputs& out) {
                      if (k % 16 == 0 && out.fk_status == haptics::FkStatus::kOk) {
                        if (session.Step(out.tool_W, false) == SculptFrameEvent::kBegan) ++strokes;
                      }
                      stroke_ticks += session.stroke_active();
                    });
  char note[200];
  std::snprintf(note, sizeof(note),
                "sculpt: %d clay vertices; stroke active in %.1f %% of ticks (%ld stroke%s)",
                session.mesh()->vertex_count(), 100.0 * stroke_ticks / ticks, strokes,
                strokes == 1 ? "" : "s");
  row.note = note;
  return row;
}

// Sculpt with the clay width: the clay of MeasureSculpt and the pinch of
// assets/trajectories/sculpt_pinch_hard.csv (scripts/make-sculpt-trajectories.py): the grip at
// rest orientation beside the clay's top lobe, where its fingertips meet the clay near 80°,
// closing its grasp towards 0.9 rad over the first 0.4 s, which begins a squeeze stroke
// (scene/clay_width.h); then it pulls 15 mm out along −b and back every 2 s, squeezing. Every
// tick samples both poles against the clay's distance grid. The session steps every 16 ticks
// (outside the timing).
Row MeasureClayPinch(const SceneTickOptions& options) {
  const long ticks = options.ticks;
  SculptSession session;
  LoadClayJson(&session);
  const Eigen::Vector3d pinch_at(-0.0404, -0.0854, 0.054);  // W = D here
  const Eigen::Vector3d out = -Eigen::Vector3d(1.0, 1.0, 0.0).normalized();
  haptics::Trajectory trajectory;
  for (int i = 0; i <= 200; ++i) {
    haptics::TrajectorySample s;
    s.t = 0.01 * i;
    s.p_DT = pinch_at + 0.0075 * (1.0 - std::cos(std::numbers::pi * i / 100.0)) * out;
    s.grasp = i < 40 ? std::numbers::pi / 2 - (std::numbers::pi / 2 - 0.9) * i / 40.0 : 0.9;
    trajectory.Add(s);
  }
  auto scene = std::make_unique<haptics::HapticScene>();
  scene->Add(session.MakeField());
  long squeeze_ticks = 0, strokes = 0;
  Row row = Measure("sculpt pinch (clay.json, clay width)", std::move(scene), BaseSettings(),
                    trajectory, options, [&](long k, const haptics::TickOutputs& out) {
                      if (k % 16 == 0 && out.fk_status == haptics::FkStatus::kOk) {
                        if (session.Step(out.tool_W, false) == SculptFrameEvent::kBegan) ++strokes;
                      }
                      squeeze_ticks += out.wrench_D(6) < 0.0;
                    });
  char note[240];
  std::snprintf(note, sizeof(note),
                "sculpt pinch: %d clay vertices, grid %ld nodes; the fingers squeeze the clay "
                "(g < 0) in %.1f %% of ticks; %ld squeeze stroke%s",
                session.mesh()->vertex_count(), session.clay_grid()->node_count(),
                100.0 * squeeze_ticks / ticks, strokes, strokes == 1 ? "" : "s");
  row.note = note;
  return row;
}

// Forwards to a field and keeps the thread CPU time of each Evaluate (µs; reserved up front).
class TimedField final : public haptics::ForceField {
 public:
  TimedField(std::unique_ptr<haptics::ForceField> field, long ticks) : field_(std::move(field)) {
    cpu_.reserve(ticks);
  }
  haptics::ToolWrench Evaluate(const haptics::ToolKinematics& tool) noexcept override {
    const double start = ThreadCpuMicros();
    const haptics::ToolWrench w = field_->Evaluate(tool);
    if (cpu_.size() < cpu_.capacity()) cpu_.push_back(ThreadCpuMicros() - start);
    return w;
  }
  const char* name() const noexcept override { return field_->name(); }
  const std::vector<double>& cpu() const { return cpu_; }

 private:
  std::unique_ptr<haptics::ForceField> field_;
  std::vector<double> cpu_;
};

// Assembly: the toy robot's AssemblyField (X_WD identity), the device calibrated as the window
// does, the hand following seat_right_leg.csv once (ticks beyond its length repeat it, each
// repeat finding the leg where the previous one left it). Rows: every tick, the carrying ticks.
std::vector<Row> MeasureAssembly(const SceneTickOptions& options) {
  const long ticks = options.ticks;
  const modeling::Scene scene = modeling::LoadScene(AssetDir() + "scenes/assembly.json");
  std::unique_ptr<haptics::AssemblyField> field = BuildAssemblyField(scene);
  haptics::AssemblyField* assembly = field.get();
  auto timed =
      std::make_unique<TimedField>(std::move(field), ticks + std::max(0L, options.warm_up_ticks));
  TimedField* timer = timed.get();
  auto haptic_scene = std::make_unique<haptics::HapticScene>();
  haptic_scene->Add(std::move(timed));
  std::vector<char> carrying;
  std::vector<double> field_cpu;  // copied out while the field lives
  field_cpu.reserve(ticks);
  carrying.reserve(ticks);
  long seated = 0;
  const int parts = assembly->size();
  Row row = Measure(
      "assembly (assembly.json, seat the right leg, every tick)", std::move(haptic_scene),
      BaseSettings(), haptics::Trajectory::Load(AssetDir() + "trajectories/seat_right_leg.csv"),
      options,
      [&](long, const haptics::TickOutputs&) {
        carrying.push_back(assembly->carried() >= 0);
        if (!timer->cpu().empty()) field_cpu.push_back(timer->cpu().back());
        seated = 0;  // the field dies with the loop: count while it lives
        for (int i = 0; i < assembly->size(); ++i) seated += assembly->seated(i);
      },
      {}, /*calibrate=*/true);
  std::vector<double> us, cpu;
  std::vector<TickCounters> counters;
  std::vector<long> index;
  for (std::size_t i = 0; i < carrying.size(); ++i) {
    if (carrying[i]) {
      us.push_back(row.us[i]);
      cpu.push_back(row.cpu[i]);
      counters.push_back(row.counters[i]);
      index.push_back(static_cast<long>(i));
    }
  }
  std::vector<double> field_carrying;
  for (std::size_t i = 0; i < carrying.size() && i < field_cpu.size(); ++i) {
    if (carrying[i]) field_carrying.push_back(field_cpu[i]);
  }
  char note[400];
  std::snprintf(note, sizeof(note),
                "assembly: a part carried in %.1f %% of ticks; %ld of %d parts seated at the end; "
                "AssemblyField::Evaluate alone (thread CPU) while carrying: p50 %.1f, p99 %.1f, "
                "p99.9 %.1f µs",
                100.0 * us.size() / ticks, seated, parts,
                field_carrying.empty() ? 0.0 : Quantile(field_carrying, 0.5),
                field_carrying.empty() ? 0.0 : Quantile(field_carrying, 0.99),
                field_carrying.empty() ? 0.0 : Quantile(field_carrying, 0.999));
  row.note = note;
  std::vector<Row> rows{row};
  if (!us.empty())
    rows.push_back(
        SummarizeTicks("assembly (the ticks carrying a part)", us, cpu, counters, index));
  return rows;
}

}  // namespace

SceneTickRow SummarizeTicks(const std::string& name, const std::vector<double>& us,
                            const std::vector<double>& cpu,
                            const std::vector<TickCounters>& counters,
                            const std::vector<long>& tick_index) {
  Row row;
  row.name = name;
  row.p50 = Quantile(us, 0.5);
  row.p99 = Quantile(us, 0.99);
  row.p999 = Quantile(us, 0.999);
  row.max = *std::max_element(us.begin(), us.end());
  row.cpu_p50 = Quantile(cpu, 0.5);
  row.cpu_p99 = Quantile(cpu, 0.99);
  row.cpu_p999 = Quantile(cpu, 0.999);
  row.cpu_max = *std::max_element(cpu.begin(), cpu.end());
  double sum = 0;
  for (double v : us) sum += v;
  row.mean = sum / us.size();
  for (const TickCounters& c : counters) {
    row.minor_faults += c.minor_faults;
    row.major_faults += c.major_faults;
    row.involuntary_switches += c.involuntary_switches;
    row.ticks_with_faults += c.minor_faults + c.major_faults > 0;
  }
  std::vector<long> order(cpu.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<long>(i);
  const std::size_t keep = std::min<std::size_t>(kSlowestTicks, order.size());
  std::partial_sort(order.begin(), order.begin() + keep, order.end(),
                    [&](long a, long b) { return cpu[a] > cpu[b] || (cpu[a] == cpu[b] && a < b); });
  for (std::size_t i = 0; i < keep; ++i) {
    SlowTick t;
    t.index =
        static_cast<std::size_t>(order[i]) < tick_index.size() ? tick_index[order[i]] : order[i];
    t.us = us[order[i]];
    t.cpu = cpu[order[i]];
    if (static_cast<std::size_t>(order[i]) < counters.size()) t.counters = counters[order[i]];
    row.slowest.push_back(t);
  }
  row.us = us;
  row.cpu = cpu;
  row.counters = counters;
  row.index = tick_index;
  return row;
}

SceneTickRow RepeatableTicks(const std::vector<const SceneTickRow*>& runs) {
  if (runs.empty()) throw std::invalid_argument("RepeatableTicks: no runs");
  for (const SceneTickRow* r : runs)
    if (r == nullptr) throw std::invalid_argument("RepeatableTicks: a null row");
  // Per run, tick index -> sample, for the ticks of the first run.
  const SceneTickRow& first = *runs.front();
  std::vector<double> us, cpu;
  std::vector<long> index;
  std::vector<std::unordered_map<long, std::size_t>> sample_of(runs.size());
  for (std::size_t r = 1; r < runs.size(); ++r) {
    sample_of[r].reserve(runs[r]->cpu.size());
    for (std::size_t i = 0; i < runs[r]->cpu.size(); ++i) sample_of[r][runs[r]->TickOf(i)] = i;
  }
  for (std::size_t i = 0; i < first.cpu.size() && i < first.us.size(); ++i) {
    const long tick = first.TickOf(i);
    double least_us = first.us[i], least_cpu = first.cpu[i];
    bool in_all = true;
    for (std::size_t r = 1; r < runs.size() && in_all; ++r) {
      const auto it = sample_of[r].find(tick);
      in_all = it != sample_of[r].end() && it->second < runs[r]->us.size();
      if (!in_all) break;
      least_us = std::min(least_us, runs[r]->us[it->second]);
      least_cpu = std::min(least_cpu, runs[r]->cpu[it->second]);
    }
    if (!in_all) continue;
    us.push_back(least_us);
    cpu.push_back(least_cpu);
    index.push_back(tick);
  }
  if (cpu.empty())
    throw std::invalid_argument("RepeatableTicks: the runs of '" + first.name + "' share no tick");
  return SummarizeTicks(first.name, us, cpu, std::vector<TickCounters>(cpu.size()), index);
}

std::vector<RepeatableRow> RepeatableRows(
    const std::vector<const std::vector<SceneTickRow>*>& runs) {
  std::vector<RepeatableRow> out;
  if (runs.empty()) return out;
  for (const SceneTickRow& row : *runs.front()) {
    RepeatableRow rep;
    for (const std::vector<SceneTickRow>* run : runs) {
      for (const SceneTickRow& r : *run) {
        if (r.name == row.name) {
          rep.runs.push_back(&r);
          break;
        }
      }
    }
    if (rep.runs.size() != runs.size()) continue;
    try {
      rep.row = RepeatableTicks(rep.runs);
    } catch (const std::invalid_argument&) {
      continue;  // the runs share no tick (a subset row)
    }
    out.push_back(std::move(rep));
  }
  return out;
}

std::vector<SceneTickRow> MeasureGoldenRunTicks(const SceneTickOptions& options, long max_ticks,
                                                const std::function<void(double)>& progress) {
  std::vector<Row> rows;
  const std::vector<GoldenRun>& runs = GoldenRuns();
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const auto setup_start = std::chrono::steady_clock::now();
    ScriptedRun run(GoldenRunOptions(runs[i], AssetDir()));
    const double setup =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - setup_start).count();
    const long ticks = max_ticks > 0 ? std::min(max_ticks, run.ticks()) : run.ticks();
    // Sized (and so touched) here: no first touch of the sample arrays between two readings.
    std::vector<double> us(ticks), cpu(ticks);
    std::vector<TickCounters> counters(ticks);
    long k = 0;
    TickCounters before;
    double cpu_start = 0.0;
    std::chrono::steady_clock::time_point start;
    run.SetStepHooks(
        [&] {
          before = ThreadCounters();
          cpu_start = ThreadCpuMicros();
          start = std::chrono::steady_clock::now();
        },
        [&] {
          const auto stop = std::chrono::steady_clock::now();
          const double cpu_stop = ThreadCpuMicros();
          counters[k] = Difference(ThreadCounters(), before);
          cpu[k] = cpu_stop - cpu_start;
          us[k] = std::chrono::duration<double, std::micro>(stop - start).count();
        });
    std::string csv;
    csv.reserve(1 << 16);
    const std::string scheduling = OnMeasuringThread(options.realtime, [&] {
      haptics::PrefaultStack();
      for (k = 0; k < ticks; ++k) {
        run.Step(&csv);
        csv.clear();
      }
    });
    run.SetStepHooks({}, {});
    run.Finish();
    Row row = SummarizeTicks("golden " + runs[i].name, us, cpu, counters);
    row.scheduling = scheduling;
    char note[300];
    std::snprintf(note, sizeof(note),
                  "golden %s: %ld of its %ld ticks (tests/golden/%s.csv; set-up %.1f s, not timed)",
                  runs[i].name.c_str(), ticks, run.ticks(), runs[i].name.c_str(), setup);
    row.note = note;
    rows.push_back(std::move(row));
    if (progress) progress(static_cast<double>(i + 1) / runs.size());
  }
  return rows;
}

std::vector<SceneTickRow> MeasureSceneTicks(long ticks,
                                            const std::function<void(double)>& progress) {
  SceneTickOptions options;
  options.ticks = ticks;
  return MeasureSceneTicks(options, progress);
}

std::vector<SceneTickRow> MeasureSceneTicks(const SceneTickOptions& given,
                                            const std::function<void(double)>& progress) {
  SceneTickOptions options = given;
  options.ticks = std::max(1L, options.ticks);
  options.warm_up_ticks = std::max(0L, options.warm_up_ticks);
  constexpr int kScenes = 7;
  int done = 0;
  auto step = [&] {
    if (progress) progress(static_cast<double>(++done) / kScenes);
  };
  std::vector<Row> rows;
  const haptics::Trajectory press =
      haptics::Trajectory::Load(AssetDir() + "trajectories/press.csv");
  rows.push_back(
      Measure("empty", std::make_unique<haptics::HapticScene>(), BaseSettings(), press, options));
  step();
  rows.push_back(Measure("demo (plane wall + spring)", haptics::MakeDemoScene(), BaseSettings(),
                         press, options));
  step();
  rows.push_back(MeasureScene("implicit proxy (platform.json, 2 solids, press)", ToolModel::kProxy,
                              Eigen::Vector3d(0.1, 0, 0.04), "trajectories/press.csv", options));
  step();
  rows.push_back(MeasureScene("six-DOF shell tool (platform.json, 196 points, twist)",
                              ToolModel::kShell, Eigen::Vector3d(0.043, 0.2, -0.1),
                              "trajectories/twist.csv", options));
  // The same with a dense shell: 50 rings of 20 points per pole.
  rows.push_back(MeasureScene("six-DOF shell tool (platform.json, 2004 points, twist)",
                              ToolModel::kShell, Eigen::Vector3d(0.043, 0.2, -0.1),
                              "trajectories/twist.csv", options, 50, 20));
  step();
  for (Row& r : MeasureFe(options)) rows.push_back(std::move(r));
  step();
  rows.push_back(MeasureSculpt(options));
  rows.push_back(MeasureClayPinch(options));
  step();
  for (Row& r : MeasureAssembly(options)) rows.push_back(std::move(r));
  step();
  return rows;
}

// Runs of the scene kinds behind the report's repeatable tick time.
constexpr int kRepeatableRuns = 3;

void ReportTick(ReportContext& ctx) {
  const long ticks = ctx.Pick(20000L, 60000L);
  // The golden runs: every tick of each (--quick: its first 2000).
  const long golden_ticks = ctx.Pick(2000L, 0L);
  SceneTickOptions options;
  options.ticks = ticks;
  options.realtime = true;  // as the window's haptic thread
  // As the window's haptic runtime: memory locked for the measurement (released after it).
  const haptics::MemoryLockResult lock = haptics::LockProcessMemory();
  std::vector<SceneTickRow> rows =
      MeasureSceneTicks(options, [&](double f) { ctx.Progress(0.3 * f); });
  const std::size_t scene_rows = rows.size();
  // The scene kinds twice more, for the repeatable tick time (RepeatableTicks).
  std::vector<std::vector<SceneTickRow>> reruns;
  for (int r = 0; r < kRepeatableRuns - 1; ++r)
    reruns.push_back(MeasureSceneTicks(
        options, [&](double f) { ctx.Progress(0.3 + 0.2 * (r + f) / (kRepeatableRuns - 1)); }));
  for (SceneTickRow& r :
       MeasureGoldenRunTicks(options, golden_ticks, [&](double f) { ctx.Progress(0.5 + 0.5 * f); }))
    rows.push_back(std::move(r));
  if (lock.status == haptics::MemoryLockStatus::kLocked) haptics::UnlockProcessMemory();
  std::vector<const std::vector<SceneTickRow>*> all_runs{&rows};
  for (const auto& run : reruns) all_runs.push_back(&run);
  const std::vector<RepeatableRow> repeatable = RepeatableRows(all_runs);
  ctx.md() << "HapticLoop::Step compute time (calibration, FK, the scene's force fields, safety, "
              "tension solve) on the simulated SPIDAR-G gripped by the simulated hand, as in "
              "`spidarcad run`, "
           << ticks
           << " ticks per scene kind (the trajectory repeats). Wall clock (steady clock) per "
              "tick; thread CPU time excludes preemption by other processes. Measuring thread: "
           << (rows.empty() ? std::string("-") : rows.front().scheduling) << "; " << lock.message
           << ". The worst tick is the CPU "
              "max column. A page fault is one the kernel counted on the measuring thread during "
              "the tick (getrusage(RUSAGE_THREAD)); the CSV adds the fault and involuntary "
              "context-switch totals. The rows named golden are the golden runs of the "
              "regression test (tests/golden, the one list in app/src/cli/golden_runs.cc): each "
              "times "
           << (golden_ticks > 0 ? "the first " + std::to_string(golden_ticks) + " ticks"
                                : std::string("every tick"))
           << " of `spidarcad run` with that golden's options, nothing else.\n";
  std::vector<std::vector<std::string>> table, csv;
  for (const SceneTickRow& r : rows) {
    table.push_back({r.name, Fixed(r.p50, 1), Fixed(r.p99, 1), Fixed(r.p999, 1), Fixed(r.max, 1),
                     Fixed(r.mean, 1), Fixed(r.cpu_p50, 1), Fixed(r.cpu_p99, 1),
                     Fixed(r.cpu_p999, 1), Fixed(r.cpu_max, 1),
                     std::to_string(r.ticks_with_faults)});
    csv.push_back({"\"" + r.name + "\"", Sig(r.p50, 6), Sig(r.p99, 6), Sig(r.p999, 6),
                   Sig(r.max, 6), Sig(r.mean, 6), Sig(r.cpu_p50, 6), Sig(r.cpu_p99, 6),
                   Sig(r.cpu_p999, 6), Sig(r.cpu_max, 6), std::to_string(r.minor_faults),
                   std::to_string(r.major_faults), std::to_string(r.ticks_with_faults),
                   std::to_string(r.involuntary_switches)});
  }
  ctx.Table({"scene", "p50 µs", "p99 µs", "p99.9 µs", "max µs", "mean µs", "CPU p50 µs",
             "CPU p99 µs", "CPU p99.9 µs", "CPU max µs", "ticks with a page fault"},
            table);
  for (const SceneTickRow& r : rows) {
    if (!r.note.empty()) ctx.md() << "- " << r.note << "\n";
  }
  ctx.md() << "\n";
  ctx.md() << "Repeatable tick time: the scene kinds were run " << kRepeatableRuns
           << " times; the simulated tick is deterministic (seeded device errors, scripted "
              "hand), so tick i does the same work in every run, and each tick's least thread CPU "
              "time over the runs leaves out what the machine charged to one run's tick "
              "(interrupts, the hypervisor: a different tick in each run). A tick slow in every "
              "run is the code's; the slowest such tick is named by its index.\n";
  std::vector<std::vector<std::string>> rep_table, rep_csv;
  for (const RepeatableRow& rep : repeatable) {
    const SceneTickRow& r = rep.row;
    const long slow = r.slowest.empty() ? -1 : r.slowest.front().index;
    std::string maxima, maxima_csv;
    for (const SceneTickRow* run : rep.runs) {
      maxima += (maxima.empty() ? "" : ", ") + Fixed(run->cpu_max, 1);
      maxima_csv += (maxima_csv.empty() ? "" : ",") + Sig(run->cpu_max, 6);
    }
    rep_table.push_back({r.name, std::to_string(r.cpu.size()), Fixed(r.cpu_p50, 1),
                         Fixed(r.cpu_p999, 1), Fixed(r.cpu_max, 1), std::to_string(slow), maxima});
    rep_csv.push_back({"\"" + r.name + "\"", std::to_string(r.cpu.size()), Sig(r.cpu_p50, 6),
                       Sig(r.cpu_p999, 6), Sig(r.cpu_max, 6), std::to_string(slow),
                       "\"" + maxima_csv + "\""});
  }
  ctx.Table({"scene", "ticks in every run", "CPU p50 µs", "CPU p99.9 µs", "CPU max µs",
             "slowest tick", "each run's CPU max µs"},
            rep_table);
  ctx.Csv("tick_repeatable",
          {"scene", "ticks", "cpu_p50_us", "cpu_p999_us", "cpu_max_us", "slowest_tick",
           "single_run_cpu_max_us"},
          rep_csv);
  ctx.Csv("tick",
          {"scene", "p50_us", "p99_us", "p999_us", "max_us", "mean_us", "cpu_p50_us", "cpu_p99_us",
           "cpu_p999_us", "cpu_max_us", "minor_faults", "major_faults", "ticks_with_faults",
           "involuntary_switches"},
          csv);
  // Distributions: the share of ticks slower than t, against t (log-log), per scene.
  Chart tail{"Tick time distribution (wall clock)",
             "tick time t [us]",
             "share of ticks slower than t",
             true,
             true,
             {}};
  Chart cpu_tail{"Tick time distribution (thread CPU)",
                 "tick time t [us]",
                 "share of ticks slower than t",
                 true,
                 true,
                 {}};
  for (size_t k = 0; k < scene_rows; ++k) {  // the scene kinds (the golden rows: the table)
    for (int which = 0; which < 2; ++which) {
      std::vector<double> v = which == 0 ? rows[k].us : rows[k].cpu;
      std::sort(v.begin(), v.end());
      ChartSeries s{rows[k].name, {}, {}, static_cast<int>(k), true, k >= 8, 0};
      const size_t n = v.size();
      // About 200 points per curve, denser in the tail.
      for (size_t i = 0; i < n; i += std::max<size_t>(1, (n - i) / 100)) {
        s.x.push_back(v[i]);
        s.y.push_back(static_cast<double>(n - i) / n);
      }
      (which == 0 ? tail : cpu_tail).series.push_back(s);
    }
  }
  ctx.Figure("tick_distribution", {tail, cpu_tail},
             "Complementary cumulative distribution of the tick time per scene: the curve at t "
             "gives the share of ticks that took longer than t (1 ms is the whole budget).",
             1600, 640);
  // The worst scenes by thread CPU time (the tick's own compute; wall-clock maxima on a shared
  // machine are the other processes' time slices).
  const SceneTickRow* worst_p999 = &rows.front();
  const SceneTickRow* worst_max = &rows.front();
  const SceneTickRow* slowest_p50 = &rows.front();
  for (const SceneTickRow& r : rows) {
    if (r.cpu_p999 > worst_p999->cpu_p999) worst_p999 = &r;
    if (r.cpu_max > worst_max->cpu_max) worst_max = &r;
    if (r.p50 > slowest_p50->p50) slowest_p50 = &r;
  }
  std::string repeatable_text;
  if (!repeatable.empty()) {
    const SceneTickRow* rp = &repeatable.front().row;
    const SceneTickRow* rm = &repeatable.front().row;
    for (const RepeatableRow& rep : repeatable) {
      if (rep.row.cpu_p999 > rp->cpu_p999) rp = &rep.row;
      if (rep.row.cpu_max > rm->cpu_max) rm = &rep.row;
    }
    repeatable_text = "; repeatable over " + std::to_string(kRepeatableRuns) +
                      " runs: worst p99.9 " + Fixed(rp->cpu_p999, 1) + " µs (" + rp->name +
                      "), worst max " + Fixed(rm->cpu_max, 1) + " µs (" + rm->name + ")";
  }
  // The headline carries the repeatable figures too: a single run's maxima on a shared machine
  // include the odd tick another process or the hypervisor slowed down.
  ctx.Headline("p50 " + Fixed(rows.front().p50, 1) + " µs (empty scene) to " +
               Fixed(slowest_p50->p50, 1) + " µs; thread CPU: worst p99.9 " +
               Fixed(worst_p999->cpu_p999, 1) + " µs (" + worst_p999->name + "), worst max " +
               Fixed(worst_max->cpu_max, 1) + " µs (" + worst_max->name + ") of the 1000 µs tick" +
               repeatable_text);
  ctx.Summary("worst p99.9 " + Fixed(worst_p999->cpu_p999, 1) + " µs (" + worst_p999->name +
                  "), worst max " + Fixed(worst_max->cpu_max, 1) + " µs (" + worst_max->name +
                  ") per tick, thread CPU" + repeatable_text,
              "— (budget 1000 µs)");
}

}  // namespace spidarcad::app
