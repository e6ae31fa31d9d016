#include "linnet/pipeline/system.h"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <optional>
#include <string>
#include <thread>
#include <utility>

#include <sched.h>

#include <opencv2/imgproc.hpp>

#include "linnet/core/cpu_clock.h"
#include "linnet/core/error.h"
#include "linnet/estimator/line_map_curation.h"
#include "linnet/features/line_tracker.h"
#include "linnet/features/point_tracker.h"
#include "linnet/pipeline/bounded_queue.h"
#include "linnet/pipeline/result_log.h"
#include "linnet/pipeline/worker_thread.h"

namespace linnet {

namespace {

using Clock = std::chrono::steady_clock;

// CPUs the process may run on (its affinity mask, e.g. under taskset); 0 when unknown.
int allowedCpus() {
#ifdef __linux__
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) == 0) return CPU_COUNT(&set);
#endif
  return 0;
}

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

struct FrameInput {
  Timestamp t = 0;
  cv::Mat left, right;
};

struct ObservationItem {
  FrameObservations obs;
  cv::Mat left;  // for the loop closer's keyframe descriptors (only when loop closure is on)
  FastCorners corners;  // left's FAST corners from the point tracker's replenishment, if it searched (likewise)
  std::vector<LbdDescriptor> line_desc;  // the line tracker's descriptors of obs.lines (likewise; empty: none)
  double frontend_ms = 0.0;
  double point_cpu_ms = 0.0;
  double line_cpu_ms = 0.0;
};

}  // namespace

struct System::Impl {
  explicit Impl(const Config& c)
      : config(c),
        cam0(CameraModel::create(c.cam0)),
        cam1(c.stereo ? CameraModel::create(c.cam1) : nullptr),
        T_C1_C0(c.cam1.T_B_C.inverse() * c.cam0.T_B_C),
        points(c.points, *cam0, cam1.get(), T_C1_C0),
        lines(c.lines, *cam0, cam1.get(), T_C1_C0),
        estimator(c.estimator, c.imu, c.cam0.T_B_C,
                  c.stereo ? std::optional<Pose>(c.cam1.T_B_C) : std::optional<Pose>()),
        loop(c.loop.enabled && c.stereo
                 ? std::make_unique<LoopCloser>(c.loop, *cam0, c.cam0.T_B_C, T_C1_C0)
                 : nullptr),
        frames(static_cast<std::size_t>(c.pipeline.frame_queue_capacity)),
        observations(static_cast<std::size_t>(c.pipeline.observation_queue_capacity)) {}

  Config config;
  std::unique_ptr<CameraModel> cam0, cam1;
  Pose T_C1_C0;
  PointTracker points;
  LineTracker lines;
  Estimator estimator;
  std::unique_ptr<LoopCloser> loop;  // touched by the estimator thread only while running

  BoundedQueue<FrameInput> frames;
  BoundedQueue<ObservationItem> observations;

  // IMU hand-over to the estimator thread.
  std::mutex imu_mutex;
  std::condition_variable imu_cv;
  std::deque<ImuSample> imu_pending;
  Timestamp last_imu_t = std::numeric_limits<Timestamp>::min();
  bool imu_closed = false;
  bool estimator_starved = false;  // the estimator waits for IMU past the newest sample
  bool frontend_starved = false;   // the front-end waits for gyroscope samples past the newest one
  std::deque<ImuSample> gyro_frontend;  // the front-end's own copy, for the rotation prediction of KLT
  Timestamp frontend_prev_t = std::numeric_limits<Timestamp>::min();

  // Results.
  mutable std::mutex result_mutex;
  // One per frame for the whole run, in 224 instead of 528 bytes (result_log.h). It grows in blocks: a vector's
  // doubling left its old buffers (half the results' size) with the allocator, and up to half its capacity unused
  // (10 minute figure-eight: resident set growth after the first minute 17.6 -> 14.4 %).
  ResultLog results;
  std::function<void(const FrameResult&)> callback;

  // First error raised in a worker thread.
  std::mutex error_mutex;
  std::exception_ptr error;

  Timestamp last_frame_t = std::numeric_limits<Timestamp>::min();
  bool finished = false;
  // With estimator.lines.map.adjust: the line map after the global adjustment (corrected world), and its figures.
  std::optional<std::vector<MapLine>> adjusted_lines;
  LineAdjustmentStats line_adjustment;

  std::unique_ptr<WorkerThread> line_worker;
  std::jthread frontend_thread, estimator_thread;

  void fail(std::exception_ptr e) {
    {
      std::lock_guard<std::mutex> lock(error_mutex);
      if (!error) error = e;
    }
    frames.close();
    observations.close();
    {
      std::lock_guard<std::mutex> lock(imu_mutex);
      imu_closed = true;
    }
    imu_cv.notify_all();
  }

  // Rotation of cam0 from the previous frame to frame t, from the raw gyroscope (a bias of 0.01 rad/s changes it by
  // 0.03 deg over 50 ms, far below what KLT notices). Waits for the IMU to cover t, so blocking runs stay
  // deterministic. Returns false when there is no previous frame or the IMU stream ended before t.
  bool gyroRotation(Timestamp t, Mat3* R_Ccur_Cprev) {
    const Timestamp t0 = frontend_prev_t;
    frontend_prev_t = t;
    Mat3 R_Bprev_Bcur = Mat3::Identity();
    {
      std::unique_lock<std::mutex> lock(imu_mutex);
      frontend_starved = last_imu_t < t;
      imu_cv.wait(lock, [&] { return imu_closed || last_imu_t >= t; });
      frontend_starved = false;
      if (t0 == std::numeric_limits<Timestamp>::min() || last_imu_t < t) return false;
      // Piecewise-constant rates: sample k holds from its time to the next sample's.
      for (std::size_t k = 0; k + 1 < gyro_frontend.size(); ++k) {
        const Timestamp a = std::max(gyro_frontend[k].t, t0), b = std::min(gyro_frontend[k + 1].t, t);
        if (b <= a) continue;
        R_Bprev_Bcur = R_Bprev_Bcur * expSO3(gyro_frontend[k].gyr * toSeconds(b - a)).toRotationMatrix();
      }
      while (gyro_frontend.size() >= 2 && gyro_frontend[1].t <= t) gyro_frontend.pop_front();
    }
    const Mat3 R_B_C = config.cam0.T_B_C.R();
    *R_Ccur_Cprev = R_B_C.transpose() * R_Bprev_Bcur.transpose() * R_B_C;
    return true;
  }

  // The line tracker's left descriptors of its delivered lines (both sorted by id); empty if one is missing.
  std::vector<LbdDescriptor> trackerDescriptors(const std::vector<LineObservation>& obs) const {
    std::vector<LbdDescriptor> out;
    out.reserve(obs.size());
    const std::vector<LineTracker::Track>& tracks = lines.tracks();
    auto it = tracks.begin();
    for (const LineObservation& o : obs) {
      it = std::lower_bound(it, tracks.end(), o.id,
                            [](const LineTracker::Track& t, std::int64_t id) { return t.id < id; });
      if (it == tracks.end() || it->id != o.id) return {};
      out.push_back(it->desc);
    }
    return out;
  }

  void frontendLoop() {
    try {
      while (std::optional<FrameInput> in = frames.pop()) {
        Mat3 R_Ccur_Cprev;
        if (gyroRotation(in->t, &R_Ccur_Cprev)) {
          points.setRotationPrediction(R_Ccur_Cprev);
          lines.setRotationPrediction(R_Ccur_Cprev);
        }
        ObservationItem item;
        item.obs.t = in->t;
        item.obs.stereo = config.stereo;
        if (loop) item.left = in->left;
        const auto t0 = Clock::now();
        auto trackLines = [&] {
          const auto tl = Clock::now();
          const double cl = threadCpuMs();
          lines.track(in->t, in->left, in->right, &item.obs.lines);
          if (loop) item.line_desc = trackerDescriptors(item.obs.lines);
          item.line_cpu_ms = threadCpuMs() - cl;
          item.obs.line_ms = msSince(tl);
        };
        if (config.pipeline.use_lines && line_worker) line_worker->submit(trackLines);
        const auto tp = Clock::now();
        const double cp = threadCpuMs();
        points.track(in->t, in->left, in->right, &item.obs.points);
        if (loop) item.corners = points.takeFastCorners();
        item.point_cpu_ms = threadCpuMs() - cp;
        item.obs.point_ms = msSince(tp);
        if (config.pipeline.use_lines) {
          if (line_worker)
            line_worker->wait();
          else
            trackLines();
        }
        item.frontend_ms = msSince(t0);
        if (!observations.push(std::move(item))) break;
      }
    } catch (...) {
      fail(std::current_exception());
    }
    observations.close();
  }

  // Moves to the estimator every IMU sample up to and including the first one at or after t.
  // Returns false if the IMU stream ended before covering t.
  bool feedImuUpTo(Timestamp t) {
    std::vector<ImuSample> batch;
    bool covered = false;
    {
      std::unique_lock<std::mutex> lock(imu_mutex);
      estimator_starved = last_imu_t < t;
      imu_cv.notify_all();
      imu_cv.wait(lock, [&] { return imu_closed || last_imu_t >= t; });
      estimator_starved = false;
      covered = last_imu_t >= t;
      while (!imu_pending.empty()) {
        const bool last = imu_pending.front().t >= t;
        batch.push_back(imu_pending.front());
        imu_pending.pop_front();
        if (last) break;
      }
    }
    for (const ImuSample& s : batch) estimator.addImu(s);
    return covered;
  }

  void estimatorLoop(std::atomic<int>* dropped) {
    try {
      while (std::optional<ObservationItem> item = observations.pop()) {
        if (!feedImuUpTo(item->obs.t)) {
          dropped->fetch_add(1);
          continue;
        }
        FrameResult r;
        const auto t0 = Clock::now();
        const double c0 = threadCpuMs();
        r.estimate = estimator.addFrame(item->obs);
        r.backend_cpu_ms = threadCpuMs() - c0;
        r.backend_ms = msSince(t0);
        r.T_W_B = r.estimate.T_W_B;
        r.v_W = r.estimate.v_W;
        std::optional<Pose> correction;
        if (loop && r.estimate.has_pose) {
          const double cl = threadCpuMs();
          if (r.estimate.keyframe && r.estimate.status == TrackingStatus::kTracking)
            loop->queueKeyframe(r.estimate.t, r.estimate.T_W_B, item->left, item->obs.points, item->obs.lines,
                                &item->corners, item->line_desc.size() == item->obs.lines.size()
                                                    ? &item->line_desc
                                                    : nullptr);
          loop->setExtrinsics(r.estimate.T_B_R * config.cam0.T_B_C);
          if (loop->hasQueued())
            loop->updateWindow(estimator.windowPoses(), estimator.pointLandmarks(), estimator.windowLines());
          correction = loop->latestCorrection();
          r.T_W_B = *correction * r.estimate.T_W_B;
          r.v_W = correction->q * r.estimate.v_W;
          r.loop_cpu_ms = threadCpuMs() - cl;
        }
        r.line_backend_ms = r.estimate.line_ms;
        r.solver_ms = r.estimate.solver_ms;
        r.point_cpu_ms = item->point_cpu_ms;
        r.line_cpu_ms = item->line_cpu_ms;
        r.frontend_ms = item->frontend_ms;
        r.point_ms = item->obs.point_ms;
        r.line_ms = item->obs.line_ms;
        r.tracked_points = static_cast<int>(item->obs.points.size());
        for (const PointObservation& p : item->obs.points) r.stereo_points += p.has_right ? 1 : 0;
        r.tracked_lines = static_cast<int>(item->obs.lines.size());
        r.rss_mb = residentSetMb();
        std::function<void(const FrameResult&)> cb;
        {
          std::lock_guard<std::mutex> lock(result_mutex);
          results.push(r, correction);
          cb = callback;
        }
        if (cb) cb(r);
      }
    } catch (...) {
      fail(std::current_exception());
    }
  }
};

System::System(const Config& config) : config_(config) {
  config_.validate();
  impl_ = std::make_unique<Impl>(config_);
  // On a single CPU the two front-end threads would only take turns on it (and on its caches): one runs after the
  // other instead.
  if (config_.pipeline.use_lines && config_.pipeline.parallel_frontend && allowedCpus() != 1)
    impl_->line_worker = std::make_unique<WorkerThread>();
  impl_->estimator_thread = std::jthread([this] { impl_->estimatorLoop(&dropped_); });
  impl_->frontend_thread = std::jthread([this] { impl_->frontendLoop(); });
}

System::~System() {
  try {
    finish();
  } catch (...) {
    // Errors are reported by an explicit finish(); a destructor must not throw.
  }
}

void System::rethrowWorkerError() {
  std::exception_ptr e;
  {
    std::lock_guard<std::mutex> lock(impl_->error_mutex);
    e = impl_->error;
  }
  if (e) std::rethrow_exception(e);
}

void System::addImu(Timestamp t, const Vec3& acc, const Vec3& gyr) {
  rethrowWorkerError();
  if (!acc.allFinite() || !gyr.allFinite())
    throw UsageError("addImu: non-finite IMU sample at t = " + std::to_string(t) + " ns");
  {
    std::lock_guard<std::mutex> lock(impl_->imu_mutex);
    if (impl_->imu_closed) throw UsageError("addImu after finish()");
    if (t <= impl_->last_imu_t)
      throw UsageError("addImu: time stamps must increase strictly (got " + std::to_string(t) + " ns after " +
                       std::to_string(impl_->last_imu_t) + " ns)");
    impl_->imu_pending.push_back(ImuSample{t, acc, gyr});
    impl_->gyro_frontend.push_back(ImuSample{t, acc, gyr});
    impl_->last_imu_t = t;
  }
  impl_->imu_cv.notify_all();
}

bool System::addStereo(Timestamp t, const cv::Mat& left, const cv::Mat& right) {
  cv::Mat l = left, r = right;  // headers shared with the caller's: addFrame copies their pixels
  return addStereo(t, std::move(l), std::move(r));
}

bool System::addMono(Timestamp t, const cv::Mat& image) {
  cv::Mat m = image;
  return addMono(t, std::move(m));
}

bool System::addStereo(Timestamp t, cv::Mat&& left, cv::Mat&& right) {
  if (!config_.stereo) throw UsageError("addStereo on a monocular System (config.stereo = false); use addMono");
  return addFrame(t, std::move(left), std::move(right));
}

bool System::addMono(Timestamp t, cv::Mat&& image) {
  if (config_.stereo) throw UsageError("addMono on a stereo System (config.stereo = true); use addStereo");
  return addFrame(t, std::move(image), cv::Mat());
}

namespace {

cv::Mat toGray(const cv::Mat& image, const CameraCalibration& calib, const char* which) {
  if (image.empty()) throw UsageError(std::string(which) + " image is empty");
  if (image.cols != calib.width || image.rows != calib.height)
    throw UsageError(std::string(which) + " image is " + std::to_string(image.cols) + "x" +
                     std::to_string(image.rows) + ", the calibration says " + std::to_string(calib.width) + "x" +
                     std::to_string(calib.height));
  if (image.depth() != CV_8U) throw UsageError(std::string(which) + " image must be 8-bit");
  if (image.channels() == 1) return image;
  cv::Mat gray;
  if (image.channels() == 3)
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  else if (image.channels() == 4)
    cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  else
    throw UsageError(std::string(which) + " image has " + std::to_string(image.channels()) + " channels");
  return gray;
}

}  // namespace

bool System::addFrame(Timestamp t, cv::Mat&& left, cv::Mat&& right) {
  rethrowWorkerError();
  if (impl_->finished) throw UsageError("add image after finish()");
  if (t <= impl_->last_frame_t)
    throw UsageError("image time stamps must increase strictly (got " + std::to_string(t) + " ns after " +
                     std::to_string(impl_->last_frame_t) + " ns)");
  // The front-end may run after this call returns: it must own its pixels. An image whose buffer only this header
  // references is already owned (the header is released below); any other is copied. (A cv::Mat wrapping the
  // caller's memory has no reference count: copied.)
  const auto alone = [](const cv::Mat& m) { return m.u != nullptr && m.u->refcount == 1; };
  const bool own_left = alone(left), own_right = alone(right);
  FrameInput in;
  in.t = t;
  in.left = toGray(left, config_.cam0, "left");
  if (config_.stereo) in.right = toGray(right, config_.cam1, "right");
  if (in.left.data == left.data && !own_left) in.left = left.clone();
  if (config_.stereo && in.right.data == right.data && !own_right) in.right = right.clone();
  left.release();
  right.release();
  impl_->last_frame_t = t;

  if (!config_.pipeline.blocking) {
    if (!impl_->frames.tryPush(std::move(in))) {
      dropped_.fetch_add(1);
      return false;
    }
    return true;
  }
  while (true) {
    using Result = BoundedQueue<FrameInput>::PushResult;
    const Result r = impl_->frames.pushFor(in, std::chrono::milliseconds(200));
    if (r == Result::kPushed) return true;
    if (r == Result::kClosed) {
      rethrowWorkerError();
      throw UsageError("System is stopped");
    }
    // Waiting longer cannot help if the estimator needs IMU data that only this thread can add.
    std::lock_guard<std::mutex> lock(impl_->imu_mutex);
    if (impl_->frontend_starved ||
        (impl_->estimator_starved && impl_->observations.size() >= impl_->observations.capacity()))
      throw UsageError(
          "blocking mode: the estimator waits for IMU samples up to the queued frames' time stamps; add IMU data "
          "(addImu) up to each frame's time before adding more frames");
  }
}

void System::setCallback(std::function<void(const FrameResult&)> callback) {
  std::lock_guard<std::mutex> lock(impl_->result_mutex);
  impl_->callback = std::move(callback);
}

void System::finish() {
  if (!impl_ || impl_->finished) {
    if (impl_) rethrowWorkerError();
    return;
  }
  impl_->finished = true;
  // End of every input stream: no more IMU either, so a frame the IMU never covered is dropped, not waited for.
  {
    std::lock_guard<std::mutex> lock(impl_->imu_mutex);
    impl_->imu_closed = true;
  }
  impl_->imu_cv.notify_all();
  impl_->frames.close();
  if (impl_->frontend_thread.joinable()) impl_->frontend_thread.join();
  if (impl_->estimator_thread.joinable()) impl_->estimator_thread.join();
  impl_->line_worker.reset();
  rethrowWorkerError();
  if (impl_->loop) {
    impl_->loop->flush();
    const LineMapOptions& mo = config_.estimator.lines.map;
    if (mo.adjust) {
      // The global adjustment of the line map: it moves the keyframes' corrections, so before the recorrection.
      LineAdjustmentOptions ao;
      const LineOptions& lo = config_.estimator.lines;
      ao.focal_px = config_.estimator.solver.focal_length;
      ao.pixel_sigma = lo.pixel_sigma;
      ao.join_px = mo.adjust_join_px;
      ao.publish_joined = mo.adjust_publish_joined;
      ao.min_depth_m = lo.min_depth_m;
      ao.max_depth_m = lo.max_depth_m;
      ao.max_length_m = lo.max_length_m;
      impl_->adjusted_lines = impl_->loop->adjustLines(impl_->estimator.mapLines(),
                                                       impl_->estimator.mapLineSightings(), ao,
                                                       &impl_->line_adjustment);
    }
    // Every frame with the final correction of its keyframe (the pose graph moved them since the callback).
    std::lock_guard<std::mutex> lock(impl_->result_mutex);
    impl_->results.recorrect([&](Timestamp t) { return impl_->loop->correctionAt(t); });
  }
}

std::vector<FrameResult> System::trajectory() const {
  std::lock_guard<std::mutex> lock(impl_->result_mutex);
  std::vector<FrameResult> out;
  out.reserve(impl_->results.size());
  for (std::size_t i = 0; i < impl_->results.size(); ++i) out.push_back(impl_->results.at(i));
  return out;
}

SystemMap System::map() const {
  // The estimator is only touched from its own thread while running; read it once the stream has finished.
  if (!impl_->finished) return {};
  SystemMap map{impl_->estimator.landmarkPositions(), {}, {}, impl_->line_adjustment};
  if (impl_->adjusted_lines) {
    map.lines = *impl_->adjusted_lines;  // already in the corrected world
  } else {
    map.lines = impl_->estimator.mapLines();
    if (impl_->loop)
      for (MapLine& l : map.lines) l = impl_->loop->correctedLine(l);
  }
  if (impl_->loop) {
    const Pose C = impl_->loop->latestCorrection();
    for (Vec3& p : map.points) p = C * p;
  }
  // The published line map (in the corrected world, where the passes over one line meet): line_map_curation.h.
  map.lines = curateLineMap(map.lines, config_.estimator.lines.map, &map.line_curation);
  return map;
}

std::vector<LoopEvent> System::loops() const {
  if (!impl_->loop || !impl_->finished) return {};
  return impl_->loop->loops();
}

LoopStats System::loopStats() const {
  if (!impl_->loop || !impl_->finished) return {};
  return impl_->loop->stats();
}

}  // namespace linnet
