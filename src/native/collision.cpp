// Collision distances in closed form (collision.hpp).
#include "ffsr/collision.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace ffsr {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kOutside = 11, kCandidates = 23;
constexpr int kPairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};

double sdf_local(double x, double y, double z, const double half[3]) {
  const double dx = std::fabs(x) - half[0], dy = std::fabs(y) - half[1], dz = std::fabs(z) - half[2];
  const double ox = std::max(dx, 0.0), oy = std::max(dy, 0.0), oz = std::max(dz, 0.0);
  const double outside = ox * ox + oy * oy + oz * oz;
  return outside > 0.0 ? std::sqrt(outside) : std::max(dx, std::max(dy, dz));
}

// Coordinate i of p in the box frame (rotation R, centre c).
double to_box(const Mat3& R, const double c[3], const double p[3], int i) {
  return R[0][i] * (p[0] - c[0]) + R[1][i] * (p[1] - c[1]) + R[2][i] * (p[2] - c[2]);
}

// Candidate k (0..22) of the parameters where the box SDF along la + t d changes formula, or -1.
double candidate(const double la[3], const double d[3], const double half[3], int k) {
  if (k < 2) return static_cast<double>(k);
  double t;
  if (k < kOutside) {
    const int i = (k - 2) / 3;
    if (d[i] == 0.0) return -1.0;
    t = (half[i] * ((k - 2) % 3 - 1) - la[i]) / d[i];
  } else {
    const int i = kPairs[(k - kOutside) / 4][0], j = kPairs[(k - kOutside) / 4][1];
    const double si = 2.0 * ((k - kOutside) % 2) - 1.0, sj = 2.0 * (((k - kOutside) / 2) % 2) - 1.0;
    const double denom = si * d[i] - sj * d[j];
    if (denom == 0.0) return -1.0;
    t = (half[i] - half[j] - si * la[i] + sj * la[j]) / denom;
  }
  return (0.0 <= t && t <= 1.0) ? t : -1.0;
}

double sdf_at(const double la[3], const double d[3], const double half[3], double t) {
  return sdf_local(la[0] + t * d[0], la[1] + t * d[1], la[2] + t * d[2], half);
}

// Minimum of the SDF on [lo, hi], a piece where it has one formula.
double piece_minimum(const double la[3], const double d[3], const double half[3], double lo, double hi) {
  const double tm = 0.5 * (lo + hi);
  double num = 0.0, den = 0.0;
  for (int i = 0; i < 3; ++i) {
    const double xi = la[i] + tm * d[i];
    if (std::fabs(xi) > half[i]) {
      const double s = xi > 0.0 ? 1.0 : -1.0;
      num -= (s * la[i] - half[i]) * s * d[i];
      den += d[i] * d[i];
    }
  }
  if (den == 0.0) return 1e300;
  return sdf_at(la, d, half, std::min(hi, std::max(lo, num / den)));
}

// Minimum over t in [0, 1] of the box SDF at la + t d (box-frame coordinates).
double segment_box_local(const double la[3], const double d[3], const double half[3]) {
  double ts[kCandidates];
  int n = 0;
  double best = 1e300;
  for (int k = 0; k < kCandidates; ++k) {
    if (k == kOutside && best > 0.0) break;  // the segment stays outside: the inside crossings do not matter
    const double t = candidate(la, d, half, k);
    if (t >= 0.0) {
      ts[n++] = t;
      best = std::min(best, sdf_at(la, d, half, t));
    }
  }
  for (int k = 1; k < n; ++k) {  // insertion sort
    const double t = ts[k];
    int j = k - 1;
    while (j >= 0 && ts[j] > t) {
      ts[j + 1] = ts[j];
      --j;
    }
    ts[j + 1] = t;
  }
  for (int k = 0; k < n - 1; ++k)
    if (ts[k + 1] > ts[k]) best = std::min(best, piece_minimum(la, d, half, ts[k], ts[k + 1]));
  return best;
}

double capsule_box(const CapsuleAxes& axes, size_t k, const Mat3& R, const double c[3], const double half[3]) {
  const double* a = &axes.A[3 * k];
  const double* b = &axes.B[3 * k];
  const double la[3] = {to_box(R, c, a, 0), to_box(R, c, a, 1), to_box(R, c, a, 2)};
  const double lb[3] = {to_box(R, c, b, 0), to_box(R, c, b, 1), to_box(R, c, b, 2)};
  const double d[3] = {lb[0] - la[0], lb[1] - la[1], lb[2] - la[2]};
  return segment_box_local(la, d, half);
}

// Distance from p to the axis of capsule k, and the vector axis point → p.
double point_capsule_axis(const double p[3], const CapsuleAxes& axes, size_t k, double e[3]) {
  const double* A = &axes.A[3 * k];
  const double* B = &axes.B[3 * k];
  const double dx = B[0] - A[0], dy = B[1] - A[1], dz = B[2] - A[2];
  double t = ((p[0] - A[0]) * dx + (p[1] - A[1]) * dy + (p[2] - A[2]) * dz) / (dx * dx + dy * dy + dz * dz);
  t = std::min(1.0, std::max(0.0, t));
  e[0] = p[0] - A[0] - t * dx, e[1] = p[1] - A[1] - t * dy, e[2] = p[2] - A[2] - t * dz;
  return std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
}

// Distance between the axes of capsules i and j (clamped closed form).
double axis_axis(const CapsuleAxes& axes, size_t i, size_t j) {
  const double* Ai = &axes.A[3 * i];
  const double* Bi = &axes.B[3 * i];
  const double* Aj = &axes.A[3 * j];
  const double* Bj = &axes.B[3 * j];
  const double d1[3] = {Bi[0] - Ai[0], Bi[1] - Ai[1], Bi[2] - Ai[2]};
  const double d2[3] = {Bj[0] - Aj[0], Bj[1] - Aj[1], Bj[2] - Aj[2]};
  const double r[3] = {Ai[0] - Aj[0], Ai[1] - Aj[1], Ai[2] - Aj[2]};
  const double a = d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2];
  const double e = d2[0] * d2[0] + d2[1] * d2[1] + d2[2] * d2[2];
  const double f = d2[0] * r[0] + d2[1] * r[1] + d2[2] * r[2];
  const double c = d1[0] * r[0] + d1[1] * r[1] + d1[2] * r[2];
  const double b = d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2];
  const double denom = a * e - b * b;
  double s = denom > 1e-14 * a * e ? std::min(1.0, std::max(0.0, (b * f - c * e) / denom)) : 0.0;
  double t = (b * s + f) / e;
  if (t < 0.0) {
    t = 0.0;
    s = std::min(1.0, std::max(0.0, -c / a));
  } else if (t > 1.0) {
    t = 1.0;
    s = std::min(1.0, std::max(0.0, (b - c) / a));
  }
  const double dx = r[0] + s * d1[0] - t * d2[0];
  const double dy = r[1] + s * d1[1] - t * d2[1];
  const double dz = r[2] + s * d1[2] - t * d2[2];
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

// Smallest signed distance of the 12 edges of box a to box b.
double edges_to_box(const Mat3& R_a, const double c_a[3], const double half_a[3], const Mat3& R_b, const double c_b[3],
                    const double half_b[3]) {
  double best = kInf;
  for (int axis = 0; axis < 3; ++axis) {
    const int j = (axis + 1) % 3, k = (axis + 2) % 3;
    const double u0 = half_a[axis] * R_a[0][axis], u1 = half_a[axis] * R_a[1][axis], u2 = half_a[axis] * R_a[2][axis];
    for (const double sj : {-half_a[j], half_a[j]}) {
      for (const double sk : {-half_a[k], half_a[k]}) {
        const double m0 = c_a[0] - c_b[0] + sj * R_a[0][j] + sk * R_a[0][k];
        const double m1 = c_a[1] - c_b[1] + sj * R_a[1][j] + sk * R_a[1][k];
        const double m2 = c_a[2] - c_b[2] + sj * R_a[2][j] + sk * R_a[2][k];
        const double la[3] = {R_b[0][0] * (m0 - u0) + R_b[1][0] * (m1 - u1) + R_b[2][0] * (m2 - u2),
                              R_b[0][1] * (m0 - u0) + R_b[1][1] * (m1 - u1) + R_b[2][1] * (m2 - u2),
                              R_b[0][2] * (m0 - u0) + R_b[1][2] * (m1 - u1) + R_b[2][2] * (m2 - u2)};
        const double d[3] = {2.0 * (R_b[0][0] * u0 + R_b[1][0] * u1 + R_b[2][0] * u2),
                             2.0 * (R_b[0][1] * u0 + R_b[1][1] * u1 + R_b[2][1] * u2),
                             2.0 * (R_b[0][2] * u0 + R_b[1][2] * u1 + R_b[2][2] * u2)};
        best = std::min(best, segment_box_local(la, d, half_b));
      }
    }
  }
  return best;
}

double pair_distance(const Robot& robot, const CapsuleAxes& axes, const Mat3& R_b, const double p_b[3], int i, int j) {
  if (j >= 0) return axis_axis(axes, i, j) - robot.capsules[i].radius - robot.capsules[j].radius;
  return capsule_box(axes, i, R_b, p_b, robot.box_half) - robot.capsules[i].radius;
}

}  // namespace

void capsule_axes(const Robot& robot, const Frames& f, const double p_b[3], CapsuleAxes& axes) {
  const size_t n = robot.capsules.size();
  axes.A.resize(3 * n);
  axes.B.resize(3 * n);
  for (size_t i = 0; i < n; ++i) {
    const Capsule& c = robot.capsules[i];
    for (int a = 0; a < 3; ++a) {
      double origin, r0, r1, r2;
      if (c.parent < 0)
        origin = p_b[a], r0 = f.R_b[a][0], r1 = f.R_b[a][1], r2 = f.R_b[a][2];
      else
        origin = f.pj[c.parent][a], r0 = f.Rj[c.parent][a][0], r1 = f.Rj[c.parent][a][1], r2 = f.Rj[c.parent][a][2];
      axes.A[3 * i + a] = origin + r0 * c.a[0] + r1 * c.a[1] + r2 * c.a[2];
      axes.B[3 * i + a] = origin + r0 * c.b[0] + r1 * c.b[1] + r2 * c.b[2];
    }
  }
}

double box_sdf(const double p[3], const Mat3& R, const double c[3], const double half[3]) {
  return sdf_local(to_box(R, c, p, 0), to_box(R, c, p, 1), to_box(R, c, p, 2), half);
}

double segment_box(const double a[3], const double b[3], const Mat3& R, const double c[3], const double half[3]) {
  const double la[3] = {to_box(R, c, a, 0), to_box(R, c, a, 1), to_box(R, c, a, 2)};
  const double lb[3] = {to_box(R, c, b, 0), to_box(R, c, b, 1), to_box(R, c, b, 2)};
  const double d[3] = {lb[0] - la[0], lb[1] - la[1], lb[2] - la[2]};
  return segment_box_local(la, d, half);
}

double obstacle_clearance(const Robot& robot, const Frames& f, const CapsuleAxes& axes, const double p_b[3],
                          const double p_o[3], double r_o, double rel[3]) {
  const auto& R_b = f.R_b;
  const double* half = robot.box_half;
  double best = box_sdf(p_o, R_b, p_b, half) - r_o;
  const double l0 = std::min(half[0], std::max(-half[0], to_box(R_b, p_b, p_o, 0)));  // nearest box point
  const double l1 = std::min(half[1], std::max(-half[1], to_box(R_b, p_b, p_o, 1)));
  const double l2 = std::min(half[2], std::max(-half[2], to_box(R_b, p_b, p_o, 2)));
  for (int a = 0; a < 3; ++a) rel[a] = p_o[a] - (p_b[a] + R_b[a][0] * l0 + R_b[a][1] * l1 + R_b[a][2] * l2);
  const double n = std::sqrt(rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2]);
  if (n > 0.0)
    for (int a = 0; a < 3; ++a) rel[a] -= r_o * rel[a] / n;
  for (size_t i = 0; i < robot.capsules.size(); ++i) {
    double e[3];
    const double dist = point_capsule_axis(p_o, axes, i, e);
    const double radius = robot.capsules[i].radius;
    const double value = dist - radius - r_o;
    if (value < best) {
      best = value;
      const double scale = dist > 0.0 ? 1.0 - (radius + r_o) / dist : 0.0;
      rel[0] = e[0] * scale, rel[1] = e[1] * scale, rel[2] = e[2] * scale;
    }
  }
  return best;
}

double body_clearance(const Robot& robot, const Frames& f, const CapsuleAxes& axes, const double p_b[3],
                      const Mat3& R_o, const double c_o[3], const double half_o[3]) {
  double best = kInf;
  for (size_t i = 0; i < robot.capsules.size(); ++i)
    best = std::min(best, capsule_box(axes, i, R_o, c_o, half_o) - robot.capsules[i].radius);
  return std::min(best, box_box(f.R_b, p_b, robot.box_half, R_o, c_o, half_o));
}

double box_box(const Mat3& R_a, const double c_a[3], const double half_a[3], const Mat3& R_b, const double c_b[3],
               const double half_b[3]) {
  return std::min(edges_to_box(R_a, c_a, half_a, R_b, c_b, half_b), edges_to_box(R_b, c_b, half_b, R_a, c_a, half_a));
}

double self_clearance(const Robot& robot, const Frames& f, CapsuleAxes& axes, const double p_b[3]) {
  const size_t n = robot.capsules.size();
  std::vector<double>& mid = axes.mid;
  std::vector<double>& hl = axes.half_length;
  std::vector<double>& bound = axes.bound;
  std::vector<int>& first = axes.first;
  std::vector<int>& second = axes.second;
  mid.resize(3 * n);
  hl.resize(n);
  bound.clear();
  first.clear();
  second.clear();
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) mid[3 * i + a] = 0.5 * (axes.A[3 * i + a] + axes.B[3 * i + a]);
    const double dx = axes.B[3 * i] - axes.A[3 * i], dy = axes.B[3 * i + 1] - axes.A[3 * i + 1],
                 dz = axes.B[3 * i + 2] - axes.A[3 * i + 2];
    hl[i] = 0.5 * std::sqrt(dx * dx + dy * dy + dz * dz);
  }
  const auto& caps = robot.capsules;
  for (size_t i = 0; i < n; ++i) {
    if (caps[i].arm == 0) {
      for (size_t j = 0; j < n; ++j) {
        if (caps[j].arm == 1) {
          const double dx = mid[3 * i] - mid[3 * j], dy = mid[3 * i + 1] - mid[3 * j + 1],
                       dz = mid[3 * i + 2] - mid[3 * j + 2];
          bound.push_back(std::sqrt(dx * dx + dy * dy + dz * dz) - hl[i] - hl[j] - caps[i].radius - caps[j].radius);
          first.push_back(static_cast<int>(i));
          second.push_back(static_cast<int>(j));
        }
      }
    }
    if (caps[i].vs_base) {
      const double* m = &mid[3 * i];
      bound.push_back(sdf_local(to_box(f.R_b, p_b, m, 0), to_box(f.R_b, p_b, m, 1), to_box(f.R_b, p_b, m, 2),
                                robot.box_half) - hl[i] - caps[i].radius);
      first.push_back(static_cast<int>(i));
      second.push_back(-1);
    }
  }
  size_t k0 = 0;
  for (size_t c = 1; c < bound.size(); ++c)
    if (bound[c] < bound[k0]) k0 = c;
  double best = pair_distance(robot, axes, f.R_b, p_b, first[k0], second[k0]);
  for (size_t c = 0; c < bound.size(); ++c)  // only pairs whose bound can still beat the best so far
    if (c != k0 && bound[c] < best) best = std::min(best, pair_distance(robot, axes, f.R_b, p_b, first[c], second[c]));
  return best;
}

}  // namespace ffsr
