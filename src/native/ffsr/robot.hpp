// The robot as the kernel reads it: joints in the paper's order (mission arm 0-5, balance arm 6-11),
// every number taken from the URDF through Pinocchio (ffsr_gym.kernel.arrays.extract), none of its own.
#pragma once

#include <vector>

#include "ffsr/linalg.hpp"

namespace ffsr {

inline constexpr int kJoints = 12;
inline constexpr int kBodies = kJoints + 1;  // body 0 is the base
inline constexpr int kStateSize = 19;        // base position, quaternion (x, y, z, w), joint angles

// A collision capsule: its axis's end points in its parent joint's frame (-1: the base) [m], its radius [m],
// its arm (0 mission, 1 balance) and whether it is checked against the base box.
struct Capsule {
  int parent;
  double a[3];
  double b[3];
  double radius;
  int arm;
  bool vs_base;
};

struct Robot {
  int parent[kJoints];               // parent joint, -1 for the base; a parent precedes its children on one arm
  double placement_R[kJoints][3][3];  // joint placement in the parent joint frame
  double placement_p[kJoints][3];
  double axis[kJoints][3];            // joint axis in the joint frame
  int axis_code[kJoints];             // 0, 1, 2: the frame's x, y or z axis (a cheaper rotation); -1 otherwise
  double mass[kBodies];               // [kg]
  double lever[kBodies][3];           // body CoM in its joint frame [m]
  double inertia[kBodies][3][3];      // about the CoM, joint frame [kg m²]
  int ee_parent[2];                   // end-effector frames (mission, balance)
  double ee_R[2][3][3];
  double ee_p[2][3];
  std::vector<Capsule> capsules;      // the arms' collision capsules
  // the servo plant's drives per joint: gain [N m s/rad], torque limit [N m] (inf: none), armature [kg m²],
  // viscous friction [N m s/rad] (zeros for the kinematic plant)
  double drive[kJoints][4];
  double box_half[3];                 // the base box's half extents [m], centred on the base frame
};

// Forward kinematics of one state (world frame).
struct Frames {
  double Rj[kJoints][3][3];  // joint frame rotations
  double pj[kJoints][3];     // joint origins
  double R_b[3][3];          // base rotation
  double Re[2][3][3];        // end-effector rotations
  double pe[2][3];           // end-effector positions
  double z[kJoints][3];      // joint axes
  double cs[3][kJoints];     // cos, sin and the angle of each joint at the last state computed afresh
};

// Momentum matrices about the base CoM (world frame) and the system CoM.
struct Momentum {
  double H_b[6][6];
  double H_bm[2][6][6];
  double rg[3];
  double comp[kJoints][10];  // composite bodies: mass, first moment, second moment (upper triangle)
};

}  // namespace ffsr
