// Free-floating multibody dynamics and the servo plant (dynamics.hpp).
#include "ffsr/dynamics.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>

namespace ffsr {
namespace {

constexpr int kMaxActiveSet = 24;

void spatial_inertia(double m, const double c[3], const Mat3& I_c, double out[6][6]) {
  for (int a = 0; a < 6; ++a)
    for (int b = 0; b < 6; ++b) out[a][b] = 0.0;
  for (int a = 0; a < 3; ++a) out[a][a] = m;
  const double cx = c[0], cy = c[1], cz = c[2];
  out[0][4] = m * cz, out[0][5] = -m * cy, out[1][3] = -m * cz, out[1][5] = m * cx, out[2][3] = m * cy,
  out[2][4] = -m * cx;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) out[3 + a][b] = -out[a][3 + b];
  const double cc = cx * cx + cy * cy + cz * cz;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) out[3 + a][3 + b] = I_c[a][b] + m * ((a == b ? cc : 0.0) - c[a] * c[b]);
}

void transforms(const Robot& robot, const double q[kJoints], Dynamics& dyn) {
  Mat3 rot;
  for (int k = 0; k < kJoints; ++k) {
    rot_about(robot.axis[k], std::cos(q[k]), std::sin(q[k]), rot);
    const auto& L = robot.placement_R[k];
    const double* p = robot.placement_p[k];
    auto& X = dyn.X[k];
    for (auto& row : X)
      for (double& value : row) value = 0.0;
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) {  // Rᵀ[a][b] = R[b][a] with R = L rot
        const double r_ba = L[b][0] * rot[0][a] + L[b][1] * rot[1][a] + L[b][2] * rot[2][a];
        X[a][b] = r_ba;
        X[3 + a][3 + b] = r_ba;
      }
    }
    for (int a = 0; a < 3; ++a) {  // the -Rᵀ S(p) block
      const double r0 = X[a][0], r1 = X[a][1], r2 = X[a][2];
      X[a][3] = r2 * p[1] - r1 * p[2], X[a][4] = r0 * p[2] - r2 * p[0], X[a][5] = r1 * p[0] - r0 * p[1];
    }
  }
}

void mv6(const double A[6][6], const double v[6], double out[6]) {
  for (int a = 0; a < 6; ++a) {
    double acc = 0.0;
    for (int b = 0; b < 6; ++b) acc += A[a][b] * v[b];
    out[a] = acc;
  }
}

void mtv6_add(const double A[6][6], const double v[6], double out[6]) {
  for (int b = 0; b < 6; ++b) {
    double acc = 0.0;
    for (int a = 0; a < 6; ++a) acc += A[a][b] * v[a];
    out[b] += acc;
  }
}

// out += Xᵀ A X for the motion transform X of a link at p in its parent, A symmetric.
void congruence_add(const double X[6][6], const double p[3], const double A[6][6], double out[6][6]) {
  double T[6][6], C[3][3];
  for (int bi = 0; bi < 6; bi += 3) {
    for (int bj = bi; bj < 6; bj += 3) {
      for (int a = 0; a < 3; ++a) {
        const double t0 = X[0][a] * A[bi][bj] + X[1][a] * A[bi + 1][bj] + X[2][a] * A[bi + 2][bj];
        const double t1 = X[0][a] * A[bi][bj + 1] + X[1][a] * A[bi + 1][bj + 1] + X[2][a] * A[bi + 2][bj + 1];
        const double t2 = X[0][a] * A[bi][bj + 2] + X[1][a] * A[bi + 1][bj + 2] + X[2][a] * A[bi + 2][bj + 2];
        for (int b = 0; b < 3; ++b) T[bi + a][bj + b] = t0 * X[0][b] + t1 * X[1][b] + t2 * X[2][b];
      }
    }
  }
  const double p0 = p[0], p1 = p[1], p2 = p[2];
  for (int r = 0; r < 3; ++r) {
    const double m0 = T[r][0], m1 = T[r][1], m2 = T[r][2];
    C[r][0] = T[r][3] + (p1 * m2 - p2 * m1);
    C[r][1] = T[r][4] + (p2 * m0 - p0 * m2);
    C[r][2] = T[r][5] + (p0 * m1 - p1 * m0);
  }
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      out[r][c] += T[r][c];
      out[r][3 + c] += C[r][c];
      out[3 + c][r] += C[r][c];
    }
  }
  for (int c = 0; c < 3; ++c) {
    const double c0 = C[0][c], c1 = C[1][c], c2 = C[2][c];
    out[3][3 + c] += p1 * c2 - p2 * c1;
    out[4][3 + c] += p2 * c0 - p0 * c2;
    out[5][3 + c] += p0 * c1 - p1 * c0;
  }
  for (int r = 0; r < 3; ++r) {
    const double b0 = T[0][3 + r], b1 = T[1][3 + r], b2 = T[2][3 + r];
    out[3 + r][3] += (p1 * b2 - p2 * b1) + T[3 + r][3];
    out[3 + r][4] += (p2 * b0 - p0 * b2) + T[3 + r][4];
    out[3 + r][5] += (p0 * b1 - p1 * b0) + T[3 + r][5];
  }
}

void cross_force_add(const double v[6], const double f[6], double out[6]) {
  const double w0 = v[3], w1 = v[4], w2 = v[5], l0 = v[0], l1 = v[1], l2 = v[2];
  const double f0 = f[0], f1 = f[1], f2 = f[2], n0 = f[3], n1 = f[4], n2 = f[5];
  out[0] += w1 * f2 - w2 * f1;
  out[1] += w2 * f0 - w0 * f2;
  out[2] += w0 * f1 - w1 * f0;
  out[3] += w1 * n2 - w2 * n1 + l1 * f2 - l2 * f1;
  out[4] += w2 * n0 - w0 * n2 + l2 * f0 - l0 * f2;
  out[5] += w0 * n1 - w1 * n0 + l0 * f1 - l1 * f0;
}

void velocities(const Robot& robot, const double v[18], Dynamics& dyn) {
  for (int a = 0; a < 6; ++a) dyn.vel[0][a] = v[a], dyn.bias[0][a] = 0.0;
  for (int k = 0; k < kJoints; ++k) {
    const int b = k + 1;
    const double dq = v[6 + k];
    mv6(dyn.X[k], dyn.vel[robot.parent[k] + 1], dyn.vel[b]);
    const double s0 = robot.axis[k][0] * dq, s1 = robot.axis[k][1] * dq, s2 = robot.axis[k][2] * dq;
    double* vb = dyn.vel[b];
    vb[3] += s0;
    vb[4] += s1;
    vb[5] += s2;
    const double l0 = vb[0], l1 = vb[1], l2 = vb[2], w0 = vb[3], w1 = vb[4], w2 = vb[5];
    double* c = dyn.bias[b];
    c[0] = l1 * s2 - l2 * s1, c[1] = l2 * s0 - l0 * s2, c[2] = l0 * s1 - l1 * s0;
    c[3] = w1 * s2 - w2 * s1, c[4] = w2 * s0 - w0 * s2, c[5] = w0 * s1 - w1 * s0;
  }
}

// One physics step h of the servo plant (see servo_period); returns whether a joint was at its limit.
bool servo_step(const Robot& plant, double x[kStateSize], double servo[kServoState], const double cmd[kJoints],
                double h, Dynamics& dyn, double tau_out[kJoints]) {
  double tau[kJoints], arm[kJoints], acc[18], side[kJoints];
  double* v = servo;
  const auto& drive = plant.drive;
  for (int j = 0; j < kJoints; ++j) {
    const double demand = drive[j][0] * (cmd[j] - v[6 + j]);
    const double limit = drive[j][1];
    side[j] = demand > limit ? 1.0 : (demand < -limit ? -1.0 : 0.0);
  }
  for (int iteration = 0; iteration < kMaxActiveSet; ++iteration) {
    for (int j = 0; j < kJoints; ++j) {
      const double gain = drive[j][0], limit = drive[j][1], friction = drive[j][3];
      const double rate = v[6 + j];
      if (side[j] == 0.0) {
        tau[j] = gain * (cmd[j] - rate) - friction * rate;
        arm[j] = drive[j][2] + h * (gain + friction);
      } else {
        tau[j] = side[j] * limit - friction * rate;
        arm[j] = drive[j][2] + h * friction;
      }
    }
    aba(plant, x + 7, v, tau, arm, dyn, acc);
    bool changed = false;
    for (int j = 0; j < kJoints; ++j) {
      const double demand = drive[j][0] * (cmd[j] - (v[6 + j] + h * acc[6 + j]));
      if (side[j] == 0.0 && std::fabs(demand) > drive[j][1]) {
        side[j] = demand > 0.0 ? 1.0 : -1.0, changed = true;
      } else if (side[j] != 0.0 && demand * side[j] < drive[j][1]) {
        side[j] = 0.0, changed = true;
      }
    }
    if (!changed) break;
  }
  bool saturated = false;
  double peak = servo[20];
  for (int j = 0; j < kJoints; ++j) {
    const double limit = drive[j][1];
    if (side[j] != 0.0) {
      tau_out[j] = side[j] * limit;
      saturated = true;
    } else {
      tau_out[j] = drive[j][0] * (cmd[j] - (v[6 + j] + h * acc[6 + j]));
    }
    if (limit < std::numeric_limits<double>::infinity()) peak = std::max(peak, std::fabs(tau_out[j]) / limit);
  }
  for (int a = 0; a < 18; ++a) v[a] += h * acc[a];
  integrate(x, v, v + 6, h, x);
  servo[18] += 1.0;
  servo[19] += saturated ? 1.0 : 0.0;
  servo[20] = peak;
  return saturated;
}

}  // namespace

void spatial_inertias(const Robot& robot, Dynamics& dyn) {
  for (int b = 0; b < kBodies; ++b) spatial_inertia(robot.mass[b], robot.lever[b], robot.inertia[b], dyn.I[b]);
}

void aba(const Robot& robot, const double q[kJoints], const double v[18], const double tau[kJoints],
         const double armature[kJoints], Dynamics& dyn, double out[18]) {
  transforms(robot, q, dyn);
  velocities(robot, v, dyn);
  double f6[6], Ia[6][6];
  for (int b = 0; b < kBodies; ++b) {
    std::memcpy(dyn.IA[b], dyn.I[b], sizeof dyn.IA[b]);
    mv6(dyn.I[b], dyn.vel[b], f6);
    for (double& value : dyn.pA[b]) value = 0.0;
    cross_force_add(dyn.vel[b], f6, dyn.pA[b]);
  }
  for (int k = kJoints - 1; k >= 0; --k) {
    const int b = k + 1;
    double* U = dyn.U[k];
    const double a0 = robot.axis[k][0], a1 = robot.axis[k][1], a2 = robot.axis[k][2];
    for (int r = 0; r < 6; ++r) U[r] = dyn.IA[b][r][3] * a0 + dyn.IA[b][r][4] * a1 + dyn.IA[b][r][5] * a2;
    const double D = a0 * U[3] + a1 * U[4] + a2 * U[5] + armature[k];
    const double u = tau[k] - (a0 * dyn.pA[b][3] + a1 * dyn.pA[b][4] + a2 * dyn.pA[b][5]);
    dyn.D[k] = D, dyn.u[k] = u;
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < 6; ++c) Ia[r][c] = dyn.IA[b][r][c] - U[r] * U[c] / D;
    double pa[6];
    mv6(Ia, dyn.bias[b], pa);
    for (int r = 0; r < 6; ++r) pa[r] += dyn.pA[b][r] + U[r] * u / D;
    const int parent = robot.parent[k] + 1;
    congruence_add(dyn.X[k], robot.placement_p[k], Ia, dyn.IA[parent]);
    mtv6_add(dyn.X[k], pa, dyn.pA[parent]);
  }
  for (int r = 0; r < 6; ++r) f6[r] = -dyn.pA[0][r];
  solve6(dyn.IA[0], f6, dyn.acc[0]);
  for (int r = 0; r < 6; ++r) out[r] = dyn.acc[0][r];
  for (int k = 0; k < kJoints; ++k) {
    const int b = k + 1;
    const double* U = dyn.U[k];
    double* acc = dyn.acc[b];
    mv6(dyn.X[k], dyn.acc[robot.parent[k] + 1], acc);
    for (int r = 0; r < 6; ++r) acc[r] += dyn.bias[b][r];
    const double dd = (dyn.u[k] - (U[0] * acc[0] + U[1] * acc[1] + U[2] * acc[2] + U[3] * acc[3] + U[4] * acc[4] +
                                   U[5] * acc[5])) / dyn.D[k];
    acc[3] += robot.axis[k][0] * dd;
    acc[4] += robot.axis[k][1] * dd;
    acc[5] += robot.axis[k][2] * dd;
    out[6 + k] = dd;
  }
}

void servo_period(const Robot& plant, double x[kStateSize], double servo[kServoState], const double cmd[kJoints],
                  double dt, int substeps, const double h[6], Dynamics& dyn, Frames& f, Momentum& m,
                  double tau_log[kJoints]) {
  spatial_inertias(plant, dyn);
  double tau[kJoints];
  for (int j = 0; j < kJoints; ++j) tau_log[j] = 0.0;
  const double step = dt / substeps;
  for (int s = 0; s < substeps; ++s) {
    servo_step(plant, x, servo, cmd, step, dyn, tau);
    for (int j = 0; j < kJoints; ++j)
      if (std::fabs(tau[j]) > std::fabs(tau_log[j])) tau_log[j] = tau[j];
  }
  kinematics(plant, x, f);  // the base twist that carries the momentum at the new joint rates
  momentum(plant, x, f, m);
  base_velocity(x, servo + 6, h, f, m, servo);
}

void drive_open_loop(const Robot& plant, double x[kStateSize], double servo[kServoState], const double* cmds, long n,
                     double h, const double h_mom[6], long every, double* x_out, double* tau_out) {
  auto dyn = std::make_unique<Dynamics>();
  auto f = std::make_unique<Frames>();
  auto m = std::make_unique<Momentum>();
  spatial_inertias(plant, *dyn);
  auto record = [&](long row) {
    std::memcpy(x_out + 40 * row, x, sizeof(double) * kStateSize);
    std::memcpy(x_out + 40 * row + kStateSize, servo, sizeof(double) * kServoState);
  };
  record(0);
  for (long k = 0; k < n; ++k) {
    servo_step(plant, x, servo, cmds + 12 * k, h, *dyn, tau_out + 12 * k);
    if (every > 0 && (k + 1) % every == 0) {
      kinematics(plant, x, *f);
      momentum(plant, x, *f, *m);
      base_velocity(x, servo + 6, h_mom, *f, *m, servo);
    }
    record(k + 1);
  }
}

}  // namespace ffsr
