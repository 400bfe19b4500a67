// Physics of the free-floating dual-arm robot (physics.hpp).
#include "ffsr/physics.hpp"

#include <cmath>

namespace ffsr {
namespace {

void mm3(const Mat3& A, const Mat3& B, Mat3& out) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out[i][j] = A[i][0] * B[0][j] + A[i][1] * B[1][j] + A[i][2] * B[2][j];
}

void mv3_add(const double base[3], const Mat3& A, const double v[3], double out[3]) {
  for (int i = 0; i < 3; ++i) out[i] = base[i] + A[i][0] * v[0] + A[i][1] * v[1] + A[i][2] * v[2];
}

// Upper triangle of the symmetric R I Rᵀ (I symmetric): out[a][b] for a <= b.
void sym_inertia(const Mat3& R, const Mat3& I, Mat3& out) {
  for (int a = 0; a < 3; ++a) {
    const double ra0 = R[a][0], ra1 = R[a][1], ra2 = R[a][2];
    const double t0 = ra0 * I[0][0] + ra1 * I[1][0] + ra2 * I[2][0];
    const double t1 = ra0 * I[0][1] + ra1 * I[1][1] + ra2 * I[2][1];
    const double t2 = ra0 * I[0][2] + ra1 * I[1][2] + ra2 * I[2][2];
    for (int b = a; b < 3; ++b) out[a][b] = t0 * R[b][0] + t1 * R[b][1] + t2 * R[b][2];
  }
}

// cos and sin of joint k of x (see kinematics).
void joint_cos_sin(const double x[kStateSize], int k, Frames& f, const double* dq, double h, double& c, double& s) {
  if (h != 0.0 && f.cs[2][k] + dq[k] * h == x[7 + k]) {
    const double d = dq[k] * h, c0 = f.cs[0][k], s0 = f.cs[1][k];
    double cd, sd;
    if (std::fabs(d) < 1e-2) {  // series to d⁹ and d⁸: below 1e-22 of the result
      const double d2 = d * d;
      sd = d * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0 * (1.0 - d2 / 42.0 * (1.0 - d2 / 72.0))));
      cd = 1.0 - d2 / 2.0 * (1.0 - d2 / 12.0 * (1.0 - d2 / 30.0 * (1.0 - d2 / 56.0)));
    } else {
      cd = std::cos(d), sd = std::sin(d);
    }
    c = c0 * cd - s0 * sd;
    s = s0 * cd + c0 * sd;
    return;
  }
  c = std::cos(x[7 + k]), s = std::sin(x[7 + k]);
  if (h == 0.0) f.cs[0][k] = c, f.cs[1][k] = s, f.cs[2][k] = x[7 + k];
}

}  // namespace

void rot_about(const double axis[3], double c, double s, Mat3& out) {
  const double x = axis[0], y = axis[1], z = axis[2], C = 1.0 - c;
  out[0][0] = c + x * x * C, out[0][1] = x * y * C - z * s, out[0][2] = x * z * C + y * s;
  out[1][0] = y * x * C + z * s, out[1][1] = c + y * y * C, out[1][2] = y * z * C - x * s;
  out[2][0] = z * x * C - y * s, out[2][1] = z * y * C + x * s, out[2][2] = c + z * z * C;
}

void quat_to_R(double qx, double qy, double qz, double qw, Mat3& R) {
  R[0][0] = 1 - 2 * (qy * qy + qz * qz), R[0][1] = 2 * (qx * qy - qz * qw), R[0][2] = 2 * (qx * qz + qy * qw);
  R[1][0] = 2 * (qx * qy + qz * qw), R[1][1] = 1 - 2 * (qx * qx + qz * qz), R[1][2] = 2 * (qy * qz - qx * qw);
  R[2][0] = 2 * (qx * qz - qy * qw), R[2][1] = 2 * (qy * qz + qx * qw), R[2][2] = 1 - 2 * (qx * qx + qy * qy);
}

void kinematics(const Robot& robot, const double x[kStateSize], Frames& f, const double* dq, double h) {
  quat_to_R(x[3], x[4], x[5], x[6], f.R_b);
  for (int k = 0; k < kJoints; ++k) {
    const int q = robot.parent[k];
    const Mat3& P = q < 0 ? f.R_b : f.Rj[q];  // the parent frame's rotation and origin
    mv3_add(q < 0 ? x : f.pj[q], P, robot.placement_p[k], f.pj[k]);
    const Mat3& L = robot.placement_R[k];
    const int a = robot.axis_code[k];
    double c, s;
    joint_cos_sin(x, k, f, dq, h, c, s);
    if (a >= 0) {  // rotation about frame axis a of P L: column a kept, the other two mixed
      const int b = (a + 1) % 3, d = (a + 2) % 3;
      for (int r = 0; r < 3; ++r) {
        const double p0 = P[r][0], p1 = P[r][1], p2 = P[r][2];
        const double ta = p0 * L[0][a] + p1 * L[1][a] + p2 * L[2][a];
        const double tb = p0 * L[0][b] + p1 * L[1][b] + p2 * L[2][b];
        const double td = p0 * L[0][d] + p1 * L[1][d] + p2 * L[2][d];
        f.Rj[k][r][a] = ta;
        f.Rj[k][r][b] = c * tb + s * td;
        f.Rj[k][r][d] = c * td - s * tb;
        f.z[k][r] = ta;
      }
    } else {
      Mat3 tmp, rot;
      mm3(P, L, tmp);
      rot_about(robot.axis[k], c, s, rot);
      mm3(tmp, rot, f.Rj[k]);
      const double* ax = robot.axis[k];
      for (int r = 0; r < 3; ++r) f.z[k][r] = f.Rj[k][r][0] * ax[0] + f.Rj[k][r][1] * ax[1] + f.Rj[k][r][2] * ax[2];
    }
  }
  for (int a = 0; a < 2; ++a) {
    const int j = robot.ee_parent[a];
    mm3(f.Rj[j], robot.ee_R[a], f.Re[a]);
    mv3_add(f.pj[j], f.Rj[j], robot.ee_p[a], f.pe[a]);
  }
}

void momentum(const Robot& robot, const double x[kStateSize], const Frames& f, Momentum& m) {
  const double x0 = x[0], x1 = x[1], x2 = x[2];
  for (auto& row : m.comp)
    for (double& value : row) value = 0.0;
  double tm = robot.mass[0], t0 = 0.0, t1 = 0.0, t2 = 0.0;  // whole robot: mass and first moment
  Mat3 W;
  sym_inertia(f.R_b, robot.inertia[0], W);
  double a00 = W[0][0], a01 = W[0][1], a02 = W[0][2], a11 = W[1][1], a12 = W[1][2], a22 = W[2][2];
  for (int i = kJoints - 1; i >= 0; --i) {
    const double mass = robot.mass[i + 1];
    const Mat3& R = f.Rj[i];
    const double* lv = robot.lever[i + 1];
    double* c = m.comp[i];
    const double dx = f.pj[i][0] - x0 + (R[0][0] * lv[0] + R[0][1] * lv[1] + R[0][2] * lv[2]);
    const double dy = f.pj[i][1] - x1 + (R[1][0] * lv[0] + R[1][1] * lv[1] + R[1][2] * lv[2]);
    const double dz = f.pj[i][2] - x2 + (R[2][0] * lv[0] + R[2][1] * lv[1] + R[2][2] * lv[2]);
    sym_inertia(R, robot.inertia[i + 1], W);
    const double mx = mass * dx, my = mass * dy, mz = mass * dz;
    c[0] += mass;
    c[1] += mx;
    c[2] += my;
    c[3] += mz;
    c[4] += W[0][0] + (my * dy + mz * dz);
    c[5] += W[0][1] - mx * dy;
    c[6] += W[0][2] - mx * dz;
    c[7] += W[1][1] + (mx * dx + mz * dz);
    c[8] += W[1][2] - my * dz;
    c[9] += W[2][2] + (mx * dx + my * dy);
    const double zx = f.z[i][0], zy = f.z[i][1], zz = f.z[i][2];
    const double ex = f.pj[i][0] - x0, ey = f.pj[i][1] - x1, ez = f.pj[i][2] - x2;
    const double Mk = c[0], Dx = c[1], Dy = c[2], Dz = c[3];
    const double fx = Dx - Mk * ex, fy = Dy - Mk * ey, fz = Dz - Mk * ez;
    const double ux = zy * ez - zz * ey, uy = zz * ex - zx * ez, uz = zx * ey - zy * ex;  // z × e
    const int arm = i / 6, col = i % 6;
    m.H_bm[arm][0][col] = zy * fz - zz * fy;
    m.H_bm[arm][1][col] = zz * fx - zx * fz;
    m.H_bm[arm][2][col] = zx * fy - zy * fx;
    m.H_bm[arm][3][col] = c[4] * zx + c[5] * zy + c[6] * zz - (Dy * uz - Dz * uy);
    m.H_bm[arm][4][col] = c[5] * zx + c[7] * zy + c[8] * zz - (Dz * ux - Dx * uz);
    m.H_bm[arm][5][col] = c[6] * zx + c[8] * zy + c[9] * zz - (Dx * uy - Dy * ux);
    const int q = robot.parent[i];
    if (q >= 0) {
      for (int a = 0; a < 10; ++a) m.comp[q][a] += c[a];
    } else {  // an arm's root: its composite joins the base
      tm += c[0], t0 += c[1], t1 += c[2], t2 += c[3];
      a00 += c[4], a01 += c[5], a02 += c[6], a11 += c[7], a12 += c[8], a22 += c[9];
    }
  }
  for (auto& row : m.H_b)
    for (double& value : row) value = 0.0;
  m.H_b[3][3] = a00, m.H_b[3][4] = a01, m.H_b[3][5] = a02;
  m.H_b[4][3] = a01, m.H_b[4][4] = a11, m.H_b[4][5] = a12;
  m.H_b[5][3] = a02, m.H_b[5][4] = a12, m.H_b[5][5] = a22;
  for (int a = 0; a < 3; ++a) m.H_b[a][a] = tm;
  m.rg[0] = x0 + t0 / tm, m.rg[1] = x1 + t1 / tm, m.rg[2] = x2 + t2 / tm;
  m.H_b[0][4] = t2, m.H_b[0][5] = -t1, m.H_b[1][3] = -t2, m.H_b[1][5] = t0, m.H_b[2][3] = t1, m.H_b[2][4] = -t0;
  m.H_b[4][0] = t2, m.H_b[5][0] = -t1, m.H_b[3][1] = -t2, m.H_b[5][1] = t0, m.H_b[3][2] = t1, m.H_b[4][2] = -t0;
}

void base_velocity(const double x[kStateSize], const double dq[kJoints], const double h[6], const Frames& f,
                   const Momentum& m, double out[6]) {
  // momentum about the base CoM, minus the arms' part
  const double ox = m.rg[0] - x[0], oy = m.rg[1] - x[1], oz = m.rg[2] - x[2];
  double rhs[6] = {h[0], h[1], h[2], h[3] + oy * h[2] - oz * h[1], h[4] + oz * h[0] - ox * h[2],
                   h[5] + ox * h[1] - oy * h[0]};
  for (int a = 0; a < 6; ++a) {
    double acc = rhs[a];
    for (int c = 0; c < 6; ++c) acc -= m.H_bm[0][a][c] * dq[c] + m.H_bm[1][a][c] * dq[6 + c];
    rhs[a] = acc;
  }
  const auto& H = m.H_b;
  const double M = H[0][0], d0 = H[5][1], d1 = H[3][2], d2 = H[4][0];
  const double inv_m = 1.0 / M;
  const double p0 = rhs[0], p1 = rhs[1], p2 = rhs[2];
  const double dd = (d0 * d0 + d1 * d1 + d2 * d2) * inv_m;
  double w[3];
  solve_sym3(H[3][3] - dd + d0 * d0 * inv_m, H[3][4] + d0 * d1 * inv_m, H[3][5] + d0 * d2 * inv_m,
             H[4][4] - dd + d1 * d1 * inv_m, H[4][5] + d1 * d2 * inv_m, H[5][5] - dd + d2 * d2 * inv_m,
             rhs[3] - (d1 * p2 - d2 * p1) * inv_m, rhs[4] - (d2 * p0 - d0 * p2) * inv_m,
             rhs[5] - (d0 * p1 - d1 * p0) * inv_m, w);
  const double v0 = (p0 + (d1 * w[2] - d2 * w[1])) * inv_m, v1 = (p1 + (d2 * w[0] - d0 * w[2])) * inv_m,
               v2 = (p2 + (d0 * w[1] - d1 * w[0])) * inv_m;
  const auto& R = f.R_b;
  for (int a = 0; a < 3; ++a) {
    out[a] = R[0][a] * v0 + R[1][a] * v1 + R[2][a] * v2;
    out[3 + a] = R[0][a] * w[0] + R[1][a] * w[1] + R[2][a] * w[2];
  }
}

void integrate(const double x[kStateSize], const double v[6], const double dq[kJoints], double dt,
               double out[kStateSize]) {
  const double wx = v[3] * dt, wy = v[4] * dt, wz = v[5] * dt;
  const double ux = v[0] * dt, uy = v[1] * dt, uz = v[2] * dt;
  const double theta2 = wx * wx + wy * wy + wz * wz;
  const double theta = std::sqrt(theta2);
  double c1, c2, half, cos_half;
  if (theta < 1e-6) {
    c1 = 0.5, c2 = 1.0 / 6.0;
    half = 0.5 - theta2 / 48.0;
    cos_half = 1.0 - theta2 / 8.0;
  } else {
    c1 = (1.0 - std::cos(theta)) / theta2, c2 = (theta - std::sin(theta)) / (theta2 * theta);
    half = std::sin(0.5 * theta) / theta;
    cos_half = std::cos(0.5 * theta);
  }
  const double ax = wy * uz - wz * uy, ay = wz * ux - wx * uz, az = wx * uy - wy * ux;  // w × u
  const double bx = wy * az - wz * ay, by = wz * ax - wx * az, bz = wx * ay - wy * ax;  // w × (w × u)
  const double vx = ux + c1 * ax + c2 * bx, vy = uy + c1 * ay + c2 * by, vz = uz + c1 * az + c2 * bz;
  const double qx = x[3], qy = x[4], qz = x[5], qw = x[6];
  // position += R(q) v, with R(q) v = v + 2 w (q × v) + 2 q × (q × v)
  const double tx = 2.0 * (qy * vz - qz * vy), ty = 2.0 * (qz * vx - qx * vz), tz = 2.0 * (qx * vy - qy * vx);
  out[0] = x[0] + vx + qw * tx + (qy * tz - qz * ty);
  out[1] = x[1] + vy + qw * ty + (qz * tx - qx * tz);
  out[2] = x[2] + vz + qw * tz + (qx * ty - qy * tx);
  const double dx = half * wx, dy = half * wy, dz = half * wz, dw = cos_half;
  const double nx = qw * dx + qx * dw + qy * dz - qz * dy;
  const double ny = qw * dy - qx * dz + qy * dw + qz * dx;
  const double nz = qw * dz + qx * dy - qy * dx + qz * dw;
  const double nw = qw * dw - qx * dx - qy * dy - qz * dz;
  const double norm = std::sqrt(nx * nx + ny * ny + nz * nz + nw * nw);
  out[3] = nx / norm, out[4] = ny / norm, out[5] = nz / norm, out[6] = nw / norm;
  for (int j = 0; j < kJoints; ++j) out[7 + j] = x[7 + j] + dq[j] * dt;
}

void midpoint(const Robot& robot, const double x[kStateSize], const double v0[6], const double dq[kJoints],
              double dt, const double h[6], Frames& f, Momentum& m, double out[kStateSize]) {
  double x_half[kStateSize], v_mid[6];
  integrate(x, v0, dq, 0.5 * dt, x_half);
  kinematics(robot, x_half, f, dq, 0.5 * dt);
  momentum(robot, x_half, f, m);
  base_velocity(x_half, dq, h, f, m, v_mid);
  integrate(x, v_mid, dq, dt, out);
}

}  // namespace ffsr
