#include "cndt/runtime/pipeline.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <boost/lockfree/spsc_queue.hpp>
#include <optional>
#include <span>

#include "cndt/core/ring_region.hpp"
#include "cndt/runtime/alloc_counter.hpp"
#include "cndt/runtime/score_threads.hpp"
#include "cndt/slam/correction_blend.hpp"

namespace cndt::runtime {
namespace {

using Clock = std::chrono::steady_clock;
constexpr auto kPoll = std::chrono::microseconds(100);

struct ScanSlot {
  core::Scan scan;
  Clock::time_point completed;
  explicit ScanSlot(std::size_t capacity) : scan(capacity) {}
};

// A scan for the mapper; its points are key_pool[points.offset, points.end()).
struct KeyScan {
  double stamp = 0.0;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  core::RingRegion points;
  std::uint64_t sequence = 0;
};

struct Ack {
  std::uint64_t sequence = 0;
  Eigen::Isometry3d correction = Eigen::Isometry3d::Identity();
};

template <class T>
using Ring = boost::lockfree::spsc_queue<T>;

double ms_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

// Minor and major page faults of the calling thread so far.
std::uint64_t thread_page_faults() noexcept {
  rusage u{};
  if (getrusage(RUSAGE_THREAD, &u) != 0) return 0;
  return static_cast<std::uint64_t>(u.ru_minflt) + static_cast<std::uint64_t>(u.ru_majflt);
}

}  // namespace

struct Pipeline::Impl {
  PipelineOptions options;
  PosePublisher& publisher;
  slam::Mapper* mapper = nullptr;
  slam::ConsensusOdometry odometry;
  std::vector<ScanSlot> slots;
  Ring<std::uint32_t> full, free_slots;
  std::vector<KeyScan> keys;
  Ring<std::uint32_t> key_full, key_free;
  // The points of the scans handed to the mapper, one after the other in a circular buffer.
  // The mapper takes scans in the order they were handed, so the odometry thread knows which
  // regions are still in use from how many scans the mapper has released.
  std::vector<Eigen::Vector3d> key_pool;
  std::vector<core::RingRegion> key_regions;  // odometry thread: by hand number modulo keys.size()
  std::uint64_t keys_handed = 0;              // odometry thread
  std::optional<std::uint32_t> held_key;      // odometry thread: a free slot taken, not yet used
  std::atomic<std::uint64_t> keys_released{0};
  Ring<Ack> acks;
  Ring<ScanResult> results;
  // Replay with the mapper, odometry thread: results whose scans went to the mapper wait here,
  // in order, for the mapper's answer to each (the correction after that scan), while the
  // odometry goes on with the next scans. At most keyframe_ring entries, so that the answers
  // waiting to be read never exceed the room of `acks`.
  struct Unpublished {
    ScanResult result;
    Clock::time_point completed;
    bool awaits_ack = false;
  };
  std::vector<Unpublished> unpublished;
  std::size_t unpublished_head = 0, unpublished_size = 0;
  slam::CorrectionBlend blend;  // odometry thread: the correction the poses are published with
  std::function<void(const slam::Mapper&, double)> keyframe_callback;
  void (*scan_callback)(void*) = nullptr;
  void* scan_context = nullptr;
  void (*mapper_scan_callback)(void*) = nullptr;
  void* mapper_scan_context = nullptr;

  std::atomic<bool> input_closed{false}, drain{true}, stopping{false};
  std::atomic<bool> odometry_done{false}, mapper_done{false};
  std::atomic<std::uint64_t> scans_in{0}, scans_dropped{0}, scans_done{0}, mapper_dropped{0},
      results_dropped{0}, keyframes{0}, allocations{0}, page_faults{0};
  std::atomic<bool> counting{false};
  // Bumped (and the waiting thread woken) whenever there may be something new for the odometry
  // thread (a scan in the ring, the input closed, a stop), for the mapper thread (a scan in the
  // key ring, the odometry done, a stop) and, in replay, for the input (room in the scan ring, a
  // scan slot freed, a stop): they sleep on these instead of polling.
  std::atomic<std::uint32_t> odometry_wake{0}, mapper_wake{0}, input_wake{0};
  static void wake(std::atomic<std::uint32_t>& w) noexcept {
    w.fetch_add(1, std::memory_order_release);
    w.notify_one();
  }
  // Live input: scans the full ring could not take yet (a FIFO on the input thread), and how
  // many of the oldest ring scans the odometry is asked to drop to make room for them.
  std::vector<std::uint32_t> pending;
  std::size_t pending_head = 0, pending_size = 0;
  std::atomic<std::uint64_t> drop_requests{0};
  // Takes one drop request if there is one (both threads take them).
  bool take_drop_request() noexcept {
    std::uint64_t v = drop_requests.load();
    while (v > 0 && !drop_requests.compare_exchange_weak(v, v - 1)) {
    }
    return v > 0;
  }
  std::thread odometry_thread, mapper_thread;
  std::unique_ptr<ScoreThreads> scorer;  // the odometry's helpers; started with it

  Impl(const PipelineOptions& o, std::size_t max_points, PosePublisher& p)
      : options(o),
        publisher(p),
        odometry(o.odometry),
        full(o.scan_ring),
        free_slots(2 * o.scan_ring + 2),
        key_full(o.keyframe_ring),
        key_free(o.keyframe_ring + 1),
        acks(o.keyframe_ring + 2),
        results(o.result_ring),
        blend(o.correction_time_constant) {
    // Pool: the ring's scans, the one in the odometry's hands, one being copied in, and (live)
    // as many waiting on the input side for the ring to make room.
    slots.reserve(2 * o.scan_ring + 2);
    pending.resize(o.scan_ring);
    for (std::size_t i = 0; i < 2 * o.scan_ring + 2; ++i) {
      slots.emplace_back(max_points);
      free_slots.push(static_cast<std::uint32_t>(i));
    }
    if (o.mapper) {
      if (!o.live) unpublished.resize(std::max<std::size_t>(1, o.keyframe_ring));
      keys.resize(o.keyframe_ring + 1);
      key_regions.resize(keys.size());
      for (std::size_t i = 0; i < keys.size(); ++i) key_free.push(static_cast<std::uint32_t>(i));
      key_pool.assign(std::max(o.keyframe_ring_points, max_points), Eigen::Vector3d::Zero());
    }
  }

  static void log_setup_problems(const char* thread, const ThreadSetup& setup) {
    const auto problems = apply_thread_setup(setup);
    for (const auto& p : problems) {
      spdlog::warn("{} thread: {}; running on without it", thread, p);
    }
    if (problems.empty() && (setup.fifo_priority > 0 || setup.cpu >= 0 || setup.nice != 0)) {
      spdlog::info("{} thread: {}{}{}", thread,
                   setup.fifo_priority > 0
                       ? fmt::format("SCHED_FIFO priority {} ", setup.fifo_priority)
                       : std::string(),
                   setup.cpu >= 0 ? fmt::format("on CPU {} ", setup.cpu) : std::string(),
                   setup.nice != 0 ? fmt::format("nice {}", setup.nice) : std::string());
    }
  }

  // Gives a scan slot back to the input (which, in replay, may be waiting for one).
  void release_slot(std::uint32_t idx) noexcept {
    free_slots.push(idx);
    wake(input_wake);
  }

  // Waits (replay) for `ok()` to hold, asleep on `w` between tries; false when stopping. `ok`
  // must become true only with a bump of `w` (or a stop) after it.
  template <class F>
  bool wait_on(std::atomic<std::uint32_t>& w, F&& ok) {
    for (;;) {
      const std::uint32_t seen = w.load(std::memory_order_acquire);
      if (ok()) return true;
      if (stopping.load()) return false;
      w.wait(seen, std::memory_order_acquire);
    }
  }

  // Waits (replay) for `ok()` to hold; false when stopping.
  template <class F>
  bool wait_for(F&& ok) {
    while (!ok()) {
      if (stopping.load(std::memory_order_relaxed)) return false;
      std::this_thread::sleep_for(kPoll);
    }
    return true;
  }

  void run_odometry() {
    log_setup_problems("odometry", options.odometry_thread);
    // Live, poses can go out before the mapper's first answer: in a prior map they are then
    // already in the map frame. (The mapper changes its correction only for scans handed to it
    // from here on.)
    Eigen::Isometry3d correction =
        mapper != nullptr ? mapper->correction() : Eigen::Isometry3d::Identity();
    std::uint64_t processed = 0, base = 0, faults_base = 0;
    for (;;) {
      std::uint32_t idx = 0;
      const std::uint32_t seen = odometry_wake.load(std::memory_order_acquire);
      if (!full.pop(idx)) {
        if (stopping.load()) break;
        if (input_closed.load() && full.read_available() == 0) break;
        odometry_wake.wait(seen, std::memory_order_acquire);  // until a scan or a stop comes
        continue;
      }
      wake(input_wake);  // replay: room in the ring
      // Live: the input found the ring full; the oldest scans (this one first) give way.
      if (options.live && take_drop_request()) {
        release_slot(idx);
        scans_dropped.fetch_add(1, std::memory_order_relaxed);
        continue;
      }
      if (stopping.load() || (input_closed.load() && !drain.load())) {
        release_slot(idx);  // a shutdown: the scans still queued are not processed
        continue;
      }
      ScanSlot& slot = slots[idx];
      ScanResult res;
      const auto t0 = Clock::now();
      res.odometry = odometry.estimate(slot.scan);  // the reference update follows the pose out
      const auto t1 = Clock::now();
      res.odometry_ms = ms_between(t0, t1);
      res.sequence = slot.scan.sequence;
      const Clock::time_point completed = slot.completed;
      const slam::OdometryResult& r = res.odometry;
      const bool skipped = (r.flags & slam::kOdomSkipped) != 0;
      res.published = r.pose;
      release_slot(idx);
      bool publishing = true;
      if (mapper != nullptr) {
        const bool handed =
            !skipped && (r.flags & slam::kOdomTooFewPoints) == 0 && hand_to_mapper(res);
        res.map_corrected = true;
        if (options.live) {
          Ack ack;
          while (acks.pop(ack)) correction = ack.correction;  // the newest finished
          send(res, completed, correction);
          commit(res);
          publishing = hand_on(res);
        } else {
          // Published once the mapper has answered for this scan, with the correction it had
          // then, as a single thread would; the odometry meanwhile goes on.
          commit(res);
          if (unpublished_size == unpublished.size()) {
            publishing = publish_unpublished(correction, true, 1);
          }
          unpublished[(unpublished_head + unpublished_size) % unpublished.size()] = {res, completed,
                                                                                     handed};
          ++unpublished_size;
          publishing = publishing && publish_unpublished(correction, false, unpublished_size);
        }
      } else {
        send(res, completed, correction);
        commit(res);
        publishing = hand_on(res);
      }
      if (!publishing) break;
      scans_done.fetch_add(1, std::memory_order_relaxed);
      ++processed;
      if (!counting.load(std::memory_order_relaxed) && processed >= options.warmup_scans) {
        base = alloc_count();
        faults_base = thread_page_faults();
        alloc_counting(true);
        counting.store(true);
      }
      if (counting.load(std::memory_order_relaxed)) {
        allocations.store(alloc_count() - base, std::memory_order_relaxed);
        page_faults.store(thread_page_faults() - faults_base, std::memory_order_relaxed);
      }
      if (scan_callback != nullptr) scan_callback(scan_context);
    }
    // Replay: the results still waiting for the mapper's answers (a shutdown takes those
    // already given and publishes the rest with the newest correction).
    publish_unpublished(correction, !stopping.load(), unpublished_size);
    alloc_counting(false);
    publisher.flush();
    odometry_done.store(true);
    wake(mapper_wake);
  }

  // Adds the scan just estimated to the odometry's reference (after its pose went out, live),
  // its time to the scan's odometry time.
  void commit(ScanResult& res) {
    const auto t0 = Clock::now();
    odometry.commit();
    res.odometry_ms += ms_between(t0, Clock::now());
  }

  // send(), then hand_on().
  bool publish(ScanResult& res, Clock::time_point completed, const Eigen::Isometry3d& correction) {
    send(res, completed, correction);
    return hand_on(res);
  }

  // Sends the pose of `res` (unless skipped) corrected by `correction`, its latency counted
  // from `completed`.
  void send(ScanResult& res, Clock::time_point completed, const Eigen::Isometry3d& correction) {
    const slam::OdometryResult& r = res.odometry;
    const bool skipped = (r.flags & slam::kOdomSkipped) != 0;
    if (res.map_corrected) {
      // A skipped scan has no pose to publish: the blend does not step.
      const Eigen::Isometry3d& applied =
          skipped ? blend.applied() : blend.step(correction, r.pose, r.dt);
      res.published = applied * r.pose;
    }
    if (!skipped) {
      res.published_pose = true;
      publisher.publish(make_pose_message(r, res.published, res.map_corrected,
                                          static_cast<std::uint32_t>(res.sequence),
                                          publisher.options()));
    }
    res.latency_ms = ms_between(completed, Clock::now());
  }

  // Hands the result on to the result side; false when stopping in replay.
  bool hand_on(ScanResult& res) {
    if (options.live) {
      if (!results.push(res)) results_dropped.fetch_add(1, std::memory_order_relaxed);
      return true;
    }
    return wait_for([&] { return results.push(res); });
  }

  // Replay with the mapper: publishes the oldest unpublished results whose answers have come
  // (each answer updates `correction`), at least `least` of them when `wait` (waiting for the
  // mapper), else as many as are ready. Stopping: the rest go out with the newest correction.
  // False when stopping.
  bool publish_unpublished(Eigen::Isometry3d& correction, bool wait, std::size_t least) {
    std::size_t published = 0;
    bool running = true;
    while (unpublished_size > 0) {
      Unpublished& u = unpublished[unpublished_head];
      // The mapper answers the scans in the order they were handed, one answer each. Shutting
      // down, it may not answer: what is left goes out as it is.
      if (running && u.awaits_ack) {
        Ack ack;
        bool answered = acks.pop(ack);
        while (!answered && !stopping.load(std::memory_order_relaxed)) {
          if (!wait || published >= least) return true;
          std::this_thread::sleep_for(kPoll);
          answered = acks.pop(ack);
        }
        if (answered) {
          correction = ack.correction;
        } else {
          running = false;
        }
      }
      running = publish(u.result, u.completed, correction) && running;
      unpublished_head = (unpublished_head + 1) % unpublished.size();
      --unpublished_size;
      ++published;
    }
    return running;
  }

  // Where `n` points can go in the key pool without touching the points of a scan the mapper
  // has not released: right after the last scan handed, or at the start of the pool.
  bool key_room(std::size_t n, core::RingRegion& region) const {
    const std::uint64_t released = keys_released.load(std::memory_order_acquire);
    const std::size_t end =
        released < keys_handed ? key_regions[(keys_handed - 1) % key_regions.size()].end() : 0;
    region = core::next_region(end, n, key_pool.size());
    for (std::uint64_t h = released; h < keys_handed; ++h) {
      if (key_regions[h % key_regions.size()].overlaps(region)) return false;
    }
    return true;
  }

  // Copies the scan's points for the mapper (replay: waits for room in the key ring). False when
  // the scan was not handed (live: no room; replay: stopping).
  bool hand_to_mapper(const ScanResult& res) {
    const auto pts = odometry.scan_points();
    const std::size_t n = std::min(pts.size(), key_pool.size());
    core::RingRegion region;
    // A free slot is not yet room in the ring: the mapper gives its scan's slot back before it
    // takes the next scan out of the ring, so the ring may still be full.
    const auto ready = [&] {
      if (!held_key) {
        std::uint32_t k = 0;
        if (key_free.pop(k)) held_key = k;
      }
      return held_key && key_full.write_available() > 0 && key_room(n, region);
    };
    if (!ready() && (options.live || !wait_for(ready))) {
      mapper_dropped.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    const std::uint32_t k = *held_key;
    held_key.reset();
    KeyScan& key = keys[k];
    key.stamp = static_cast<double>(res.odometry.stamp.count()) * 1e-9;
    key.pose = res.odometry.pose;
    key.points = region;
    std::copy(pts.begin(), pts.begin() + static_cast<std::ptrdiff_t>(n),
              key_pool.begin() + static_cast<std::ptrdiff_t>(region.offset));
    key.sequence = res.sequence;
    key_regions[keys_handed % key_regions.size()] = region;
    ++keys_handed;
    key_full.push(k);
    wake(mapper_wake);
    return true;
  }

  void run_mapper() {
    log_setup_problems("mapper", options.mapper_thread);
    for (;;) {
      std::uint32_t k = 0;
      const std::uint32_t seen = mapper_wake.load(std::memory_order_acquire);
      if (!key_full.pop(k)) {
        const bool odometry_finished = odometry_done.load();
        if (stopping.load() || (odometry_finished && key_full.read_available() == 0)) break;
        mapper_wake.wait(seen, std::memory_order_acquire);  // until a scan or the end comes
        continue;
      }
      KeyScan& key = keys[k];
      const auto t0 = Clock::now();
      const bool closed = mapper->add(
          key.stamp, key.pose,
          std::span<const Eigen::Vector3d>(key_pool).subspan(key.points.offset, key.points.count));
      keys_released.fetch_add(1, std::memory_order_release);  // its points were copied
      if (closed) {
        keyframes.fetch_add(1);
        if (keyframe_callback) keyframe_callback(*mapper, ms_between(t0, Clock::now()));
      }
      acks.push(Ack{key.sequence, mapper->correction()});
      key_free.push(k);
      if (mapper_scan_callback != nullptr) mapper_scan_callback(mapper_scan_context);
    }
    if (!stopping.load() || input_closed.load()) {
      const auto t0 = Clock::now();
      mapper->flush();
      if (!mapper->refined().empty()) {
        keyframes.fetch_add(1);
        if (keyframe_callback) keyframe_callback(*mapper, ms_between(t0, Clock::now()));
      }
    }
    mapper_done.store(true);
  }
};

Pipeline::Pipeline(const PipelineOptions& options, std::size_t max_scan_points,
                   PosePublisher& publisher)
    : impl_(std::make_unique<Impl>(options, max_scan_points, publisher)) {
  if (options.mapper) {
    mapper_ = std::make_unique<slam::Mapper>(options.mapper_options);
    impl_->mapper = mapper_.get();
  }
}

Pipeline::~Pipeline() {
  stop();
  join();
}

void Pipeline::start_from(slam::NdtMap&& map, const Eigen::Isometry3d& T_map_odom) {
  if (mapper_) mapper_->start_from(std::move(map), T_map_odom);
}

void Pipeline::on_keyframe(std::function<void(const slam::Mapper&, double)> callback) {
  impl_->keyframe_callback = std::move(callback);
}

void Pipeline::on_scan_done(void (*callback)(void*), void* context) {
  impl_->scan_callback = callback;
  impl_->scan_context = context;
}

void Pipeline::on_mapper_scan_done(void (*callback)(void*), void* context) {
  impl_->mapper_scan_callback = callback;
  impl_->mapper_scan_context = context;
}

void Pipeline::start() {
  if (impl_->options.scoring_threads > 1) {
    ThreadSetup helper = impl_->options.odometry_thread;
    helper.cpu = -1;
    impl_->scorer = std::make_unique<ScoreThreads>(impl_->options.scoring_threads - 1, helper);
    impl_->odometry.set_score_runner(impl_->scorer.get());
  }
  impl_->odometry_thread = std::thread([this] { impl_->run_odometry(); });
  if (mapper_) {
    impl_->mapper_thread = std::thread([this] { impl_->run_mapper(); });
  } else {
    impl_->mapper_done.store(true);
  }
}

bool Pipeline::push(const core::Scan& scan, std::chrono::steady_clock::time_point completed) {
  Impl& m = *impl_;
  if (m.stopping.load()) return false;
  if (m.options.live) service_input();
  std::uint32_t idx = 0;
  // Replay: a free slot exists whenever the ring has room. Live: the pool covers the ring, the
  // odometry's scan, a full pending FIFO and one more; when the FIFO is full its oldest scan
  // gives way and its slot takes the new one (the free list has a single producer, the
  // odometry, so the input never puts slots back itself).
  if (m.options.live) {
    if (m.pending_size == m.pending.size()) {
      idx = m.pending[m.pending_head];
      m.pending_head = (m.pending_head + 1) % m.pending.size();
      --m.pending_size;
      m.take_drop_request();  // its request goes with it (unless already served)
      m.scans_dropped.fetch_add(1, std::memory_order_relaxed);
    } else if (!m.free_slots.pop(idx)) {
      return false;  // cannot happen with the pool's size
    }
  } else if (!m.wait_on(m.input_wake, [&] { return m.free_slots.pop(idx); })) {
    return false;
  }
  ScanSlot& slot = m.slots[idx];
  slot.scan = scan;  // within the slot's capacity: no allocation
  slot.completed = completed;
  m.scans_in.fetch_add(1, std::memory_order_relaxed);
  if (m.options.live) {
    if (m.pending_size == 0 && m.full.push(idx)) {
      Impl::wake(m.odometry_wake);
      return true;
    }
    // The ring is full: the scan waits on this side, and the odometry drops the oldest ring
    // scan for it at its next step. The input never waits for the odometry.
    m.pending[(m.pending_head + m.pending_size) % m.pending.size()] = idx;
    ++m.pending_size;
    m.drop_requests.fetch_add(1);
    return true;
  }
  // Stopped while waiting: the slot stays out of the pool, which is going away.
  if (!m.wait_on(m.input_wake, [&] { return m.full.push(idx); })) return false;
  Impl::wake(m.odometry_wake);
  return true;
}

void Pipeline::service_input() {
  Impl& m = *impl_;
  bool pushed = false;
  while (m.pending_size > 0 && m.full.push(m.pending[m.pending_head])) {
    m.pending_head = (m.pending_head + 1) % m.pending.size();
    --m.pending_size;
    pushed = true;
  }
  if (pushed) Impl::wake(m.odometry_wake);
}

void Pipeline::close_input(bool drain) {
  if (impl_->options.live && drain) {
    // Scans still pending on the input side go in as the ring makes room.
    while (impl_->pending_size > 0 && !impl_->stopping.load()) {
      service_input();
      if (impl_->pending_size > 0) std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
  }
  impl_->drain.store(drain);
  impl_->input_closed.store(true);
  Impl::wake(impl_->odometry_wake);
}

void Pipeline::stop() {
  impl_->stopping.store(true);
  Impl::wake(impl_->odometry_wake);
  Impl::wake(impl_->mapper_wake);
  Impl::wake(impl_->input_wake);
}

bool Pipeline::pop(ScanResult& out) { return impl_->results.pop(out); }

bool Pipeline::done() const {
  return impl_->odometry_done.load() && impl_->mapper_done.load() &&
         impl_->results.read_available() == 0;
}

void Pipeline::join() {
  if (impl_->odometry_thread.joinable()) impl_->odometry_thread.join();
  if (impl_->mapper_thread.joinable()) impl_->mapper_thread.join();
}

PipelineStats Pipeline::stats() const {
  const Impl& m = *impl_;
  PipelineStats s;
  s.scans_in = m.scans_in.load();
  s.scans_dropped = m.scans_dropped.load();
  s.scans_done = m.scans_done.load();
  s.mapper_dropped = m.mapper_dropped.load();
  s.results_dropped = m.results_dropped.load();
  s.keyframes = m.keyframes.load();
  s.heap_allocations_in_odometry = m.allocations.load();
  s.page_faults_in_odometry = m.page_faults.load();
  s.allocations_counted = m.counting.load();
  return s;
}

}  // namespace cndt::runtime
