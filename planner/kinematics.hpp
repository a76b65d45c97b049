// Kinematics behind one interface: Cartesian position (x, y, z of the nozzle, mm) <-> joint
// positions (3 motors, mm), reachability of points and of whole straight segments.
// Implementations: cartesian and corexy (linear maps, kinematics.cpp) and delta (delta_kinematics).
// The extruder is not a kinematic joint; the planner carries E beside the three joints.
#pragma once

#include <array>
#include <memory>

#include "core/result.hpp"
#include "planner/config.hpp"

namespace feedloop::planner {

using Vec3 = std::array<double, 3>;
using Joints = std::array<double, 3>;

class Kinematics {
 public:
  virtual ~Kinematics() = default;
  virtual KinematicsKind kind() const = 0;

  // Joint positions of a reachable point (no check; call check_point first). RT-safe.
  virtual Joints inverse(const Vec3& p_mm) const = 0;
  // Joint velocities for Cartesian velocity v at point p (qdot = J^-1 Xdot). RT-safe.
  virtual Joints joint_velocity(const Vec3& p_mm, const Vec3& v_mm_s) const = 0;
  // Both at once (the delta shares the square roots). RT-safe.
  virtual void inverse_with_velocity(const Vec3& p_mm, const Vec3& v_mm_s, Joints& q_mm, Joints& qdot_mm_s) const {
    q_mm = inverse(p_mm);
    qdot_mm_s = joint_velocity(p_mm, v_mm_s);
  }
  // Cartesian position from joint positions; an error when the joints are inconsistent.
  virtual Result<Vec3> forward(const Joints& q_mm) const = 0;

  // Is the point inside the workspace and the travel limits? The error says which limit failed.
  virtual Status check_point(const Vec3& p_mm) const = 0;
  // Is every point of the straight segment a -> b reachable?
  virtual Status check_segment(const Vec3& a_mm, const Vec3& b_mm) const = 0;

  // True when joints are a constant linear map of x, y, z (then a trapezoid phase is exactly a
  // quadratic in every joint); linear_map() returns that matrix, rows = joints.
  virtual bool is_linear() const = 0;
  virtual std::array<Vec3, 3> linear_map() const { return {}; }
};

// Builds the kinematics the config names (validated config assumed).
std::unique_ptr<Kinematics> make_kinematics(const PlannerConfig& config);

}  // namespace feedloop::planner
