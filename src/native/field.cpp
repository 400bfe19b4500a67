// The danger field of an arm (docs/model.md §14, §22): the CDF of every obstacle point, and of a tumbling
// target's centre, along the arm's segments in closed form, its joint-space gradient and the blend μ.
#include "field.hpp"

#include <cmath>
#include <limits>

namespace ffsr {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The segment's ends as distances along it from the foot of the perpendicular (lo <= hi, lo >= 0 when the foot
// is off the segment), with their distances to the point.
void ordered_ends(double length, double t0, double rho1, double rho2, double& lo, double& hi, double& r_lo,
                  double& r_hi) {
  const double tau1 = -t0, tau2 = length - t0;
  if (tau2 > 0.0)
    lo = tau1, hi = tau2, r_lo = rho1, r_hi = rho2;
  else
    lo = -tau2, hi = -tau1, r_lo = rho2, r_hi = rho1;
}

// Integral of 1/ρ along segment i seen from (ox, oy, oz), and the nearest distance; keeps (length, t0, h,
// ρ1, ρ2) in geometry. A zero-length segment gives (0, inf).
void field_of_segment(double ox, double oy, double oz, const double points[7][3], int i, double geometry[5],
                      double& F, double& nearest) {
  const double ax = points[i][0], ay = points[i][1], az = points[i][2];
  const double Lx = points[i + 1][0] - ax, Ly = points[i + 1][1] - ay, Lz = points[i + 1][2] - az;
  const double length = std::sqrt(Lx * Lx + Ly * Ly + Lz * Lz);
  geometry[0] = length;
  if (length < 1e-12) {
    F = 0.0, nearest = kInf;
    return;
  }
  const double wx = ox - ax, wy = oy - ay, wz = oz - az;
  const double t0 = (wx * Lx + wy * Ly + wz * Lz) / length;
  const double cx = Ly * wz - Lz * wy, cy = Lz * wx - Lx * wz, cz = Lx * wy - Ly * wx;
  const double h = std::max(std::sqrt(cx * cx + cy * cy + cz * cz) / length, 1e-12);
  const double rho1 = std::sqrt(wx * wx + wy * wy + wz * wz);
  const double vx = wx - Lx, vy = wy - Ly, vz = wz - Lz;
  const double rho2 = std::sqrt(vx * vx + vy * vy + vz * vz);
  geometry[1] = t0, geometry[2] = h, geometry[3] = rho1, geometry[4] = rho2;
  double lo, hi, r_lo, r_hi;
  ordered_ends(length, t0, rho1, rho2, lo, hi, r_lo, r_hi);
  if (lo >= 0.0) {  // the foot of the perpendicular is off the segment
    F = std::log((hi + r_hi) / (lo + r_lo)) / length, nearest = r_lo;
    return;
  }
  F = std::log((hi + r_hi) * (r_lo - lo) / (h * h)) / length, nearest = h;
}

// (I0, I1): the integrals of 1/ρ³ and s/ρ³ along a segment, from its geometry.
void moments_of_segment(const double geometry[5], double& I0, double& I1) {
  const double length = geometry[0], t0 = geometry[1], h = geometry[2], rho1 = geometry[3], rho2 = geometry[4];
  double lo, hi, r_lo, r_hi;
  ordered_ends(length, t0, rho1, rho2, lo, hi, r_lo, r_hi);
  const double inv3 = lo >= 0.0 ? (hi * hi - lo * lo) / (r_lo * r_hi * (hi * r_lo + lo * r_hi))
                                 : (hi / r_hi - lo / r_lo) / (h * h);
  I0 = inv3 / length;
  I1 = (1.0 / rho1 - 1.0 / rho2) / (length * length) + (t0 / length) * I0;
}

}  // namespace

void obstacle_at(const Obstacle& o, double t, double out[3]) {
  for (int a = 0; a < 3; ++a) out[a] = o.position[a] + o.velocity[a] * t;
}

const Frame& frame_at(const PlannerSettings& s, double t) {
  const long k = static_cast<long>(std::floor(t / s.dt + 0.5));
  const long last = static_cast<long>(s.frames.size()) - 1;
  return s.frames[static_cast<size_t>(k < last ? k : last)];
}

void avoidance(const PlannerSettings& s, const Frames& f, int arm, double t, Plan& p, double& mu, double& cdf) {
  auto& points = p.points;
  for (int a = 0; a < 3; ++a) {
    for (int i = 0; i < 6; ++i) points[i][a] = f.pj[6 * arm + i][a];
    points[6][a] = f.pe[arm][a];
  }
  double total = 0.0, dist = 1e300;
  const int n_obs = static_cast<int>(s.obstacles.size());
  double o_at[3];
  for (int o = 0; o < n_obs; ++o) {
    obstacle_at(s.obstacles[o], t, o_at);
    for (int i = 0; i < 6; ++i) {
      double F, nearest;
      field_of_segment(o_at[0], o_at[1], o_at[2], points, i, p.seg[6 * o + i], F, nearest);
      total += F;
      dist = nearest < dist ? nearest : dist;
    }
  }
  double ratio = n_obs > 0 ? dist / s.danger_radius : kInf;
  const bool body = s.body_danger > 0.0;
  if (body) {  // the tumbling body's centre: every segment but the tool's, seen from its bounding sphere
    const double* c = frame_at(s, t).centre;
    double near = kInf;
    for (int i = 0; i < 5; ++i) {
      double F, nearest;
      field_of_segment(c[0], c[1], c[2], points, i, p.seg[6 * kMaxObstacles + i], F, nearest);
      total += F;
      near = nearest < near ? nearest : near;
    }
    const double body_ratio = (near - s.body_radius) / s.body_danger;
    ratio = body_ratio < ratio ? body_ratio : ratio;
  }
  cdf = s.k1 * total;
  if (!s.mu_distance) {
    mu = cdf <= s.delta ? 1.0 : s.delta / cdf;
  } else {
    const double r = 1.0 < ratio ? 1.0 : ratio;
    mu = r * r;
  }
  if (s.method == Method::kNoAvoidance || (arm == 1 && !s.balance_avoids)) mu = 1.0;
  for (double& v : p.dq_c) v = 0.0;
  if (mu >= 1.0) {
    mu = 1.0;
    return;
  }
  const double scale = -s.xi * s.k1;  // Θ̇_c = −ξ k₁ ∂CDF/∂Θ, only needed while the avoidance acts
  for (int o = 0; o < (body ? n_obs + 1 : n_obs); ++o) {
    double ox, oy, oz;
    int base;
    if (o < n_obs) {
      obstacle_at(s.obstacles[o], t, o_at);
      ox = o_at[0], oy = o_at[1], oz = o_at[2];
      base = 6 * o;
    } else {
      const double* c = frame_at(s, t).centre;
      ox = c[0], oy = c[1], oz = c[2];
      base = 6 * kMaxObstacles;
    }
    for (int i = 0; i < (o < n_obs ? 6 : 5); ++i) {
      const double* geometry = p.seg[base + i];
      if (geometry[0] < 1e-12) continue;  // zero-length segment
      double I0, I1;
      moments_of_segment(geometry, I0, I1);
      const double ax = points[i][0], ay = points[i][1], az = points[i][2];
      const double bx = points[i + 1][0], by = points[i + 1][1], bz = points[i + 1][2];
      for (int k = 0; k <= i; ++k) {
        const double px = points[k][0], py = points[k][1], pz = points[k][2];
        double ux = ax - px, uy = ay - py, uz = az - pz;  // c0 = (a − p_k) × (p_o − a)
        double wx = ox - ax, wy = oy - ay, wz = oz - az;
        const double c0x = uy * wz - uz * wy, c0y = uz * wx - ux * wz, c0z = ux * wy - uy * wx;
        ux = bx - ax, uy = by - ay, uz = bz - az;  // c1 = (b − a) × (p_o − p_k)
        wx = ox - px, wy = oy - py, wz = oz - pz;
        const double c1x = uy * wz - uz * wy, c1y = uz * wx - ux * wz, c1z = ux * wy - uy * wx;
        const int j = 6 * arm + k;
        p.dq_c[k] += scale * (f.z[j][0] * (c0x * I0 + c1x * I1) + f.z[j][1] * (c0y * I0 + c1y * I1) +
                              f.z[j][2] * (c0z * I0 + c1z * I1));
      }
    }
  }
}

void segment_field(const double p[3], const double a[3], const double b[3], double& F, double& nearest, double& I0,
                   double& I1) {
  double points[7][3] = {};
  for (int k = 0; k < 3; ++k) points[0][k] = a[k], points[1][k] = b[k];
  double geometry[5] = {};
  field_of_segment(p[0], p[1], p[2], points, 0, geometry, F, nearest);
  I0 = I1 = 0.0;
  if (std::isfinite(nearest)) moments_of_segment(geometry, I0, I1);
}

}  // namespace ffsr
