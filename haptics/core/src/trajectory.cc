// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/trajectory.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <istream>
#include <limits>
#include <ostream>
#include <sstream>
#include <stdexcept>

namespace spidarcad::haptics {

namespace {

constexpr const char* kFields[9] = {"t", "x", "y", "z", "qw", "qx", "qy", "qz", "grasp"};

std::string Trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

[[noreturn]] void Fail(const std::string& source, int line, const std::string& field,
                       const std::string& message) {
  std::ostringstream os;
  os << source << ":" << line << ": ";
  if (!field.empty()) os << "field '" << field << "': ";
  os << message;
  throw std::invalid_argument(os.str());
}

std::string Format(double v) {
  char buffer[64];
  const auto r = std::to_chars(buffer, buffer + sizeof(buffer), v);
  return std::string(buffer, r.ptr);
}

void CheckGenerator(double duration, double rate) {
  if (!(duration > 0 && std::isfinite(duration))) {
    throw std::invalid_argument("trajectory generator: duration " + Format(duration) +
                                " s must be finite and > 0");
  }
  if (!(rate > 0 && std::isfinite(rate))) {
    throw std::invalid_argument("trajectory generator: rate " + Format(rate) +
                                " Hz must be finite and > 0");
  }
}

int SampleCount(double duration, double rate) {
  return std::max(2, static_cast<int>(std::ceil(duration * rate)) + 1);
}

// Smooth step 0 -> 1 on [0, 1] (cosine).
double Blend(double s) {
  s = std::min(1.0, std::max(0.0, s));
  return 0.5 - 0.5 * std::cos(M_PI * s);
}

Eigen::Vector3d AnyPerpendicular(const Eigen::Vector3d& a) {
  const Eigen::Vector3d other =
      std::abs(a.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  return a.cross(other).normalized();
}

}  // namespace

Trajectory Trajectory::Parse(std::istream& in, const std::string& source) {
  Trajectory trajectory;
  std::string raw;
  int line = 0;
  while (std::getline(in, raw)) {
    ++line;
    const std::string text = Trim(raw);
    if (text.empty() || text[0] == '#') continue;
    double v[9];
    int count = 0;
    std::size_t begin = 0;
    while (true) {
      const std::size_t comma = text.find(',', begin);
      const std::string field =
          Trim(text.substr(begin, comma == std::string::npos ? std::string::npos : comma - begin));
      if (count >= 9) {
        Fail(source, line, "", "too many fields (expected 9: t,x,y,z,qw,qx,qy,qz,grasp)");
      }
      double value = 0;
      const char* first = field.data();
      const char* last = field.data() + field.size();
      const auto r = std::from_chars(first, last, value);
      if (field.empty() || r.ec != std::errc() || r.ptr != last) {
        Fail(source, line, kFields[count], "'" + field + "' is not a number");
      }
      if (!std::isfinite(value)) Fail(source, line, kFields[count], "value is not finite");
      v[count++] = value;
      if (comma == std::string::npos) break;
      begin = comma + 1;
    }
    if (count != 9) {
      Fail(source, line, "",
           std::to_string(count) + " fields, expected 9: t,x,y,z,qw,qx,qy,qz,grasp");
    }
    TrajectorySample s;
    s.t = v[0];
    s.p_DT = Eigen::Vector3d(v[1], v[2], v[3]);
    Eigen::Quaterniond q(v[4], v[5], v[6], v[7]);
    const double norm = q.norm();
    if (std::abs(norm - 1.0) > 1e-3) {
      Fail(source, line, "qw",
           "quaternion (" + Format(v[4]) + "," + Format(v[5]) + "," + Format(v[6]) + "," +
               Format(v[7]) + ") has norm " + Format(norm) + ", expected 1");
    }
    s.q_DT = q.normalized();
    if (!(v[8] > 0 && v[8] < M_PI)) {
      Fail(source, line, "grasp", "grasp angle " + Format(v[8]) + " rad is not in (0, π)");
    }
    s.grasp = v[8];
    if (!trajectory.samples_.empty() && !(s.t > trajectory.samples_.back().t)) {
      Fail(source, line, "t",
           "time " + Format(s.t) + " s does not increase (previous " +
               Format(trajectory.samples_.back().t) + " s)");
    }
    trajectory.samples_.push_back(s);
  }
  if (trajectory.samples_.empty()) throw std::invalid_argument(source + ": no samples");
  return trajectory;
}

Trajectory Trajectory::Load(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::invalid_argument(path + ": cannot open the trajectory file");
  return Parse(in, path);
}

void Trajectory::Write(std::ostream& out) const {
  out << "# t,x,y,z,qw,qx,qy,qz,grasp (s, m in the device frame D, unit quaternion R_DT, rad)\n";
  for (const TrajectorySample& s : samples_) {
    out << Format(s.t) << ',' << Format(s.p_DT.x()) << ',' << Format(s.p_DT.y()) << ','
        << Format(s.p_DT.z()) << ',' << Format(s.q_DT.w()) << ',' << Format(s.q_DT.x()) << ','
        << Format(s.q_DT.y()) << ',' << Format(s.q_DT.z()) << ',' << Format(s.grasp) << '\n';
  }
}

void Trajectory::Add(const TrajectorySample& sample) {
  if (!samples_.empty() && !(sample.t > samples_.back().t)) {
    throw std::invalid_argument("Trajectory::Add: time " + Format(sample.t) +
                                " s does not increase");
  }
  samples_.push_back(sample);
}

TrajectorySample Trajectory::Sample(double t) const noexcept {
  if (t <= samples_.front().t) return samples_.front();
  if (t >= samples_.back().t) return samples_.back();
  const auto it = std::upper_bound(samples_.begin(), samples_.end(), t,
                                   [](double v, const TrajectorySample& s) { return v < s.t; });
  const TrajectorySample& b = *it;
  const TrajectorySample& a = *(it - 1);
  // Times more than the largest double apart: b.t - a.t overflows; their halves do not.
  const double s = std::isfinite(b.t - a.t) ? (t - a.t) / (b.t - a.t)
                                            : (0.5 * t - 0.5 * a.t) / (0.5 * b.t - 0.5 * a.t);
  TrajectorySample out;
  out.t = t;
  out.p_DT = a.p_DT + s * (b.p_DT - a.p_DT);
  // Coordinates of opposite signs that far apart: b - a overflows; the weighted sum does not.
  if (!out.p_DT.allFinite()) out.p_DT = (1.0 - s) * a.p_DT + s * b.p_DT;
  out.q_DT = a.q_DT.slerp(s, b.q_DT);
  out.grasp = a.grasp + s * (b.grasp - a.grasp);
  return out;
}

Trajectory ApproachPressRelease(const Eigen::Vector3d& start, const Eigen::Vector3d& surface,
                                const Eigen::Vector3d& normal, double depth, double duration,
                                double rate) {
  CheckGenerator(duration, rate);
  if (normal.norm() < 1e-12) throw std::invalid_argument("ApproachPressRelease: zero normal");
  const Eigen::Vector3d n = normal.normalized();
  const Eigen::Vector3d pressed = surface - depth * n;
  Trajectory tr;
  const int count = SampleCount(duration, rate);
  for (int k = 0; k < count; ++k) {
    const double t = duration * k / (count - 1);
    const double u = t / duration;
    TrajectorySample s;
    s.t = t;
    if (u < 0.4) {
      s.p_DT = start + Blend(u / 0.4) * (surface - start);
    } else if (u < 0.6) {
      s.p_DT = surface + Blend((u - 0.4) / 0.2) * (pressed - surface);
    } else if (u < 0.7) {
      s.p_DT = pressed;
    } else {
      s.p_DT = pressed + Blend((u - 0.7) / 0.3) * (start - pressed);
    }
    tr.Add(s);
  }
  return tr;
}

Trajectory Circle(const Eigen::Vector3d& center, double radius, const Eigen::Vector3d& axis,
                  double turns, double duration, double rate) {
  CheckGenerator(duration, rate);
  if (axis.norm() < 1e-12) throw std::invalid_argument("Circle: zero axis");
  const Eigen::Vector3d a = axis.normalized();
  const Eigen::Vector3d u = AnyPerpendicular(a);
  const Eigen::Vector3d v = a.cross(u);
  Trajectory tr;
  const int count = SampleCount(duration, rate);
  for (int k = 0; k < count; ++k) {
    const double t = duration * k / (count - 1);
    const double phi = 2 * M_PI * turns * Blend(t / duration);
    TrajectorySample s;
    s.t = t;
    s.p_DT = center + radius * (std::cos(phi) * u + std::sin(phi) * v);
    tr.Add(s);
  }
  return tr;
}

Trajectory Twist(const Eigen::Vector3d& center, const Eigen::Vector3d& axis, double amplitude,
                 double cycles, double duration, double rate) {
  CheckGenerator(duration, rate);
  if (axis.norm() < 1e-12) throw std::invalid_argument("Twist: zero axis");
  Trajectory tr;
  const int count = SampleCount(duration, rate);
  for (int k = 0; k < count; ++k) {
    const double t = duration * k / (count - 1);
    TrajectorySample s;
    s.t = t;
    s.p_DT = center;
    s.q_DT = Eigen::Quaterniond(Eigen::AngleAxisd(
        amplitude * std::sin(2 * M_PI * cycles * t / duration), axis.normalized()));
    tr.Add(s);
  }
  return tr;
}

Trajectory Squeeze(const Eigen::Vector3d& center, double grasp_min, double cycles, double duration,
                   double rate) {
  CheckGenerator(duration, rate);
  if (!(grasp_min > 0 && grasp_min < M_PI)) {
    throw std::invalid_argument("Squeeze: grasp_min " + Format(grasp_min) +
                                " rad is not in (0, π)");
  }
  Trajectory tr;
  const int count = SampleCount(duration, rate);
  for (int k = 0; k < count; ++k) {
    const double t = duration * k / (count - 1);
    TrajectorySample s;
    s.t = t;
    s.p_DT = center;
    const double c = 0.5 - 0.5 * std::cos(2 * M_PI * cycles * t / duration);
    s.grasp = M_PI / 2 + c * (grasp_min - M_PI / 2);
    tr.Add(s);
  }
  return tr;
}

}  // namespace spidarcad::haptics
