// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Synthetic stereo scenes: YAML loading and a per-pixel ray-casting renderer (see scene.h).
#include "stereo_pf/sim/scene.h"
#include "stereo_pf/sim/scene_sensor.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <initializer_list>
#include <optional>
#include <set>
#include <sstream>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "scene_detail.h"

namespace stereo_pf
{
namespace
{
constexpr double kPi = 3.14159265358979323846;
constexpr double kGravity = 9.81;

double deg2rad(double d) { return d * kPi / 180.0; }

std::string vecText(const Eigen::Vector3d& v)
{
  std::ostringstream s;
  s << "[" << v.x() << ", " << v.y() << ", " << v.z() << "]";
  return s.str();
}

// Triangle wave that keeps x inside [lo, hi] as if reflected at both ends (bouncing, closed form so
// frame k never depends on earlier frames).
double reflect(double x, double lo, double hi)
{
  const double span = hi - lo;
  double m = std::fmod(x - lo, 2.0 * span);
  if (m < 0.0)
    m += 2.0 * span;
  return m <= span ? lo + m : lo + 2.0 * span - m;
}

// Pixel extent [lo, hi] (continuous coordinates) of a sphere seen from a camera at the origin along
// one image axis. The tangent planes through the optical centre containing the other axis satisfy
// (c - a cz)^2 = r^2 (1 + a^2) for a = (u - c0) / f; both roots give the exact silhouette extremes.
bool sphereExtent(double c, double cz, double r, double f, double c0, double& lo, double& hi)
{
  const double den = cz * cz - r * r;
  if (cz <= r * 1.0001 || den <= 0.0)
    return false;  // camera inside or behind the ball: not rendered
  const double root = r * std::sqrt(c * c + den);
  lo = c0 + f * (c * cz - root) / den;
  hi = c0 + f * (c * cz + root) / den;
  return true;
}

struct PixelBox
{
  double u0, u1, v0, v1;
};

bool sphereBox(const SceneCamera& cam, const Eigen::Vector3d& c_rel, double r, PixelBox& box)
{
  return sphereExtent(c_rel.x(), c_rel.z(), r, cam.fx, cam.cx, box.u0, box.u1) &&
         sphereExtent(c_rel.y(), c_rel.z(), r, cam.fy, cam.cy, box.v0, box.v1);
}

// Pixel box of a square patch facing the camera (normal along -z), centre c_rel relative to the camera,
// half side r: an axis-aligned rectangle at constant depth.
bool squareBox(const SceneCamera& cam, const Eigen::Vector3d& c_rel, double r, PixelBox& box)
{
  const double z = c_rel.z();
  if (z <= 1e-3)
    return false;  // behind the camera (or at it): not rendered
  box.u0 = cam.cx + cam.fx * (c_rel.x() - r) / z;
  box.u1 = cam.cx + cam.fx * (c_rel.x() + r) / z;
  box.v0 = cam.cy + cam.fy * (c_rel.y() - r) / z;
  box.v1 = cam.cy + cam.fy * (c_rel.y() + r) / z;
  return true;
}

bool isSolid(const SceneSphere& s)
{
  return s.shape == SceneSphere::Shape::Box || s.shape == SceneSphere::Shape::Cylinder;
}

// Image extent of any scene object at time t.
bool objectBox(const SceneCamera& cam, const SceneSphere& s, const Eigen::Vector3d& c_rel, double t, PixelBox& box)
{
  if (isSolid(s))
    return scene_detail::solidExtent(cam, s, s.orientation(t), c_rel, box.u0, box.u1, box.v0, box.v1);
  return s.shape == SceneSphere::Shape::Square ? squareBox(cam, c_rel, s.radius, box) :
                                                 sphereBox(cam, c_rel, s.radius, box);
}

// Nearest positive ray parameter where origin + t * dir enters the sphere, or +inf.
double raySphere(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, const Eigen::Vector3d& centre, double r)
{
  const Eigen::Vector3d oc = centre - origin;
  const double dd = dir.squaredNorm();
  const double proj = dir.dot(oc) / dd;
  const double perp2 = oc.squaredNorm() - proj * proj * dd;
  if (perp2 > r * r)
    return std::numeric_limits<double>::infinity();
  const double half = std::sqrt((r * r - perp2) / dd);
  const double t = proj - half;
  if (t > 1e-9)
    return t;
  return proj + half > 1e-9 ? proj + half : std::numeric_limits<double>::infinity();
}

// Ray parameter where origin + t * dir hits a square facing the camera (centre, half side r), or +inf.
double raySquare(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, const Eigen::Vector3d& centre, double r)
{
  if (std::abs(dir.z()) < 1e-12)
    return std::numeric_limits<double>::infinity();
  const double t = (centre.z() - origin.z()) / dir.z();
  if (!(t > 1e-9))
    return std::numeric_limits<double>::infinity();
  const Eigen::Vector3d p = origin + t * dir;
  return std::abs(p.x() - centre.x()) <= r && std::abs(p.y() - centre.y()) <= r ?
             t :
             std::numeric_limits<double>::infinity();
}

// Ray parameter of the first hit with any scene object at its position `centre` at time t, or +inf.
double rayObject(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, const SceneSphere& s,
                 const Eigen::Vector3d& centre, double t)
{
  if (isSolid(s))
  {
    scene_detail::SolidHit hit;
    const bool hits = scene_detail::solidRay(s, s.orientation(t), centre - origin, dir, hit);
    return hits ? hit.t : std::numeric_limits<double>::infinity();
  }
  return s.shape == SceneSphere::Shape::Square ? raySquare(origin, dir, centre, s.radius) :
                                                 raySphere(origin, dir, centre, s.radius);
}

// ------------------------------------------------------------------------------------------------
// YAML reading with error messages that name the file and the field.
class SceneReader
{
public:
  explicit SceneReader(const std::string& path) : path_(path) {}

  [[noreturn]] void fail(const std::string& field, const std::string& what) const
  {
    throw SceneError("cannot read scene '" + path_ + "': field '" + field + "': " + what);
  }

  static std::string join(const std::string& parent, const std::string& key)
  {
    return parent.empty() ? key : parent + "." + key;
  }

  // Typos in optional keys would otherwise silently fall back to defaults: reject unknown and duplicated keys.
  void checkKeys(const cv::FileNode& map, const std::string& field, std::initializer_list<const char*> known) const
  {
    if (!map.isMap())
      fail(field.empty() ? "<top level>" : field, "must be a mapping of key: value");
    std::set<std::string> seen;
    for (cv::FileNodeIterator it = map.begin(); it != map.end(); ++it)
    {
      const std::string key = (*it).name();
      if (!seen.insert(key).second)
        fail(join(field, key), "given twice");
      bool ok = false;
      std::string list;
      for (const char* k : known)
      {
        ok = ok || key == k;
        list += list.empty() ? k : std::string(", ") + k;
      }
      if (!ok)
        fail(join(field, key), "unknown key (allowed here: " + list + ")");
    }
  }

  static bool has(const cv::FileNode& map, const char* key) { return !map[key].isNone(); }

  double number(const cv::FileNode& map, const std::string& parent, const char* key, const double* fallback,
                double min, double max) const
  {
    const cv::FileNode n = map[key];
    const std::string field = join(parent, key);
    if (n.isNone())
    {
      if (!fallback)
        fail(field, "missing (required)");
      return *fallback;
    }
    if (!n.isInt() && !n.isReal())
      fail(field, "must be a number, got " + describe(n));
    const double v = n.real();
    if (!std::isfinite(v) || v < min || v > max)
    {
      std::ostringstream s;
      s << "must be in [" << min << ", " << max << "], got " << v;
      fail(field, s.str());
    }
    return v;
  }
  double number(const cv::FileNode& map, const std::string& parent, const char* key, double fallback, double min,
                double max) const
  {
    return number(map, parent, key, &fallback, min, max);
  }
  double required(const cv::FileNode& map, const std::string& parent, const char* key, double min, double max) const
  {
    return number(map, parent, key, nullptr, min, max);
  }

  int integer(const cv::FileNode& map, const std::string& parent, const char* key, int fallback, int min, int max) const
  {
    const cv::FileNode n = map[key];
    if (!n.isNone() && !n.isInt())
      fail(join(parent, key), "must be an integer, got " + describe(n));
    return static_cast<int>(number(map, parent, key, static_cast<double>(fallback), min, max));
  }

  std::string text(const cv::FileNode& map, const std::string& parent, const char* key, const std::string& fallback,
                   std::initializer_list<const char*> allowed = {}) const
  {
    const cv::FileNode n = map[key];
    const std::string field = join(parent, key);
    if (n.isNone())
    {
      if (fallback.empty() && allowed.size() > 0)
        fail(field, "missing (required; one of: " + listOf(allowed) + ")");
      return fallback;
    }
    if (!n.isString())
      fail(field, "must be a string, got " + describe(n));
    const std::string v = clean(n.string());
    if (allowed.size() > 0)
    {
      for (const char* a : allowed)
        if (v == a)
          return v;
      fail(field, "got '" + v + "', allowed: " + listOf(allowed));
    }
    return v;
  }

  bool boolean(const cv::FileNode& map, const std::string& parent, const char* key, bool fallback) const
  {
    const cv::FileNode n = map[key];
    if (n.isNone())
      return fallback;
    if (n.isInt() && (n.real() == 0.0 || n.real() == 1.0))
      return n.real() != 0.0;
    const std::string v = n.isString() ? clean(n.string()) : std::string();
    if (v == "true" || v == "yes" || v == "True")
      return true;
    if (v == "false" || v == "no" || v == "False")
      return false;
    fail(join(parent, key), "must be true or false, got " + describe(n));
  }

  std::vector<double> numbers(const cv::FileNode& n, const std::string& field, size_t size) const
  {
    if (!n.isSeq() || (size > 0 && n.size() != size))
      fail(field, "must be a list of " + std::to_string(size) + " numbers, got " + describe(n));
    std::vector<double> out;
    for (cv::FileNodeIterator it = n.begin(); it != n.end(); ++it)
    {
      const cv::FileNode e = *it;
      if (!e.isInt() && !e.isReal())
        fail(field, "must be a list of numbers, element " + std::to_string(out.size()) + " is " + describe(e));
      out.push_back(e.real());
    }
    return out;
  }

  Eigen::Vector3d vec3(const cv::FileNode& map, const std::string& parent, const char* key,
                       const Eigen::Vector3d* fallback) const
  {
    const cv::FileNode n = map[key];
    if (n.isNone())
    {
      if (!fallback)
        fail(join(parent, key), "missing (required; a list [x, y, z] in metres)");
      return *fallback;
    }
    const std::vector<double> v = numbers(n, join(parent, key), 3);
    return Eigen::Vector3d(v[0], v[1], v[2]);
  }

  // Colours are written RGB (what people expect) and stored BGR (what OpenCV draws).
  cv::Vec3d colour(const cv::FileNode& map, const std::string& parent, const char* key, const cv::Vec3d& fallback) const
  {
    const cv::FileNode n = map[key];
    if (n.isNone())
      return fallback;
    const std::string field = join(parent, key);
    const std::vector<double> v = numbers(n, field, 3);
    for (double c : v)
      if (c < 0.0 || c > 255.0)
        fail(field, "RGB components must be in [0, 255]");
    return cv::Vec3d(v[2], v[1], v[0]);
  }

  static std::string describe(const cv::FileNode& n)
  {
    if (n.isString())
      return "'" + clean(n.string()) + "'";
    if (n.isSeq())
      return "a list of " + std::to_string(n.size());
    if (n.isMap())
      return "a mapping";
    if (n.isInt() || n.isReal())
    {
      std::ostringstream s;
      s << n.real();
      return s.str();
    }
    return "nothing";
  }

  // OpenCV keeps "value  # comment" as the string value: drop the comment and blanks.
  static std::string clean(std::string s)
  {
    const size_t hash = s.find('#');
    if (hash != std::string::npos)
      s.erase(hash);
    const size_t end = s.find_last_not_of(" \t\r");
    return end == std::string::npos ? std::string() : s.substr(0, end + 1);
  }

  static std::string listOf(std::initializer_list<const char*> items)
  {
    std::string s;
    for (const char* i : items)
      s += s.empty() ? i : std::string(", ") + i;
    return s;
  }

  const std::string& path() const { return path_; }

private:
  std::string path_;
};

// [x, y, z] with every component in [min, max].
Eigen::Vector3d rangedVec3(const SceneReader& r, const cv::FileNode& n, const std::string& parent, const char* key,
                           const Eigen::Vector3d* fallback, double min, double max)
{
  const Eigen::Vector3d v = r.vec3(n, parent, key, fallback);
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(v[a]) || v[a] < min || v[a] > max)
    {
      std::ostringstream s;
      s << "every component must be in [" << min << ", " << max << "], got " << vecText(v);
      r.fail(SceneReader::join(parent, key), s.str());
    }
  return v;
}

// The ballistic and random_walk trajectory types.
Trajectory readNewMotion(const SceneReader& r, const cv::FileNode& n, const std::string& field, const std::string& type)
{
  Trajectory tr;
  if (type == "ballistic")
  {
    r.checkKeys(n, field, { "type", "start", "velocity", "gravity", "t0", "floor_y", "restitution" });
    const Eigen::Vector3d zero = Eigen::Vector3d::Zero(), down = tr.gravity;
    tr = Trajectory::ballistic(rangedVec3(r, n, field, "start", nullptr, -1e4, 1e4),
                               rangedVec3(r, n, field, "velocity", &zero, -1e3, 1e3),
                               rangedVec3(r, n, field, "gravity", &down, -1e3, 1e3),
                               r.number(n, field, "t0", 0.0, -1e6, 1e6));
    tr.has_floor = SceneReader::has(n, "floor_y");
    if (SceneReader::has(n, "restitution") && !tr.has_floor)
      r.fail(SceneReader::join(field, "restitution"), "only with floor_y (the plane the ball bounces off)");
    if (tr.has_floor)
    {
      tr.floor_y = r.required(n, field, "floor_y", -1e4, 1e4);
      tr.restitution = r.number(n, field, "restitution", tr.restitution, 0.0, 1.0);
      if (tr.position.y() > tr.floor_y)
      {
        std::ostringstream s;
        s << "start y " << tr.position.y() << " is below the floor (y is down): start y must be <= floor_y "
          << tr.floor_y;
        r.fail(SceneReader::join(field, "start"), s.str());
      }
    }
  }
  else
  {
    r.checkKeys(n, field, { "type", "centre", "extent", "speed", "seed" });
    const Eigen::Vector3d extent = rangedVec3(r, n, field, "extent", nullptr, 0.0, 100.0);
    if (!(extent.maxCoeff() > 0.0))
      r.fail(SceneReader::join(field, "extent"), "must be > 0 on at least one axis (half sizes, metres)");
    tr = Trajectory::randomWalk(rangedVec3(r, n, field, "centre", nullptr, -1e4, 1e4), extent,
                                r.number(n, field, "speed", tr.speed, 1e-6, 100.0),
                                static_cast<uint64_t>(r.integer(n, field, "seed", 1, 0, 2147483647)));
  }
  return tr;
}

Trajectory readTrajectory(const SceneReader& r, const cv::FileNode& n, const std::string& field, double duration)
{
  if (n.isNone())
    r.fail(field, "missing (required)");
  const std::string type = r.text(n, field, "type", "",
                                  { "static", "linear", "waypoints", "pendulum", "bounce", "ballistic",
                                    "random_walk" });
  Trajectory tr;
  if (type == "static")
  {
    r.checkKeys(n, field, { "type", "position" });
    tr = Trajectory::fixed(r.vec3(n, field, "position", nullptr));
  }
  else if (type == "linear")
  {
    r.checkKeys(n, field, { "type", "from", "to", "t_start", "t_end" });
    const double t0 = r.number(n, field, "t_start", 0.0, -1e6, 1e6);
    const double t1 = r.number(n, field, "t_end", duration, -1e6, 1e6);
    if (!(t1 > t0))
      r.fail(SceneReader::join(field, "t_end"), "must be after t_start");
    tr = Trajectory::linear(r.vec3(n, field, "from", nullptr), r.vec3(n, field, "to", nullptr), t0, t1);
  }
  else if (type == "waypoints")
  {
    r.checkKeys(n, field, { "type", "times", "points" });
    const cv::FileNode times = n["times"];
    const cv::FileNode points = n["points"];
    if (times.isNone() || points.isNone())
      r.fail(field, "waypoints need 'times' (seconds) and 'points' (list of [x, y, z])");
    tr.type = Trajectory::Type::Waypoints;
    tr.times = r.numbers(times, SceneReader::join(field, "times"), 0);
    if (!points.isSeq() || points.size() != tr.times.size())
      r.fail(SceneReader::join(field, "points"), "must be a list of as many [x, y, z] as there are times");
    int i = 0;
    for (cv::FileNodeIterator it = points.begin(); it != points.end(); ++it, ++i)
    {
      const std::string element = SceneReader::join(field, "points") + "[" + std::to_string(i) + "]";
      const std::vector<double> p = r.numbers(*it, element, 3);
      tr.points.emplace_back(p[0], p[1], p[2]);
    }
  }
  else if (type == "pendulum")
  {
    r.checkKeys(n, field, { "type", "pivot", "length", "amplitude_deg", "period", "phase_deg", "plane_angle_deg" });
    const double length = r.required(n, field, "length", 1e-3, 100.0);
    // Default period: the physical one of a simple pendulum of that length.
    const double period = r.number(n, field, "period", 2.0 * kPi * std::sqrt(length / kGravity), 1e-3, 1e4);
    tr = Trajectory::pendulum(r.vec3(n, field, "pivot", nullptr), length,
                              deg2rad(r.required(n, field, "amplitude_deg", 0.0, 89.0)), period,
                              deg2rad(r.number(n, field, "phase_deg", 0.0, -3600.0, 3600.0)),
                              deg2rad(r.number(n, field, "plane_angle_deg", 0.0, -90.0, 90.0)));
  }
  else if (type == "ballistic" || type == "random_walk")
  {
    tr = readNewMotion(r, n, field, type);
  }
  else  // bounce
  {
    r.checkKeys(n, field, { "type", "start", "velocity", "box_min", "box_max" });
    tr = Trajectory::bounce(r.vec3(n, field, "start", nullptr), r.vec3(n, field, "velocity", nullptr),
                            r.vec3(n, field, "box_min", nullptr), r.vec3(n, field, "box_max", nullptr));
  }
  const std::string problem = tr.validate();
  if (!problem.empty())
    r.fail(field, problem);
  return tr;
}

void readPresence(const SceneReader& r, const cv::FileNode& n, const std::string& field, Trajectory& tr)
{
  tr.t_enter = r.number(n, field, "t_enter", tr.t_enter, -1e9, 1e9);
  tr.t_leave = r.number(n, field, "t_leave", tr.t_leave, -1e9, 1e9);
  if (!(tr.t_leave > tr.t_enter))
    r.fail(SceneReader::join(field, "t_leave"), "must be after t_enter");
}

// An object's shape and the dimensions that go with it; keys of other shapes are errors naming the field.
void readShape(const SceneReader& r, const cv::FileNode& n, const std::string& f, SceneSphere& s)
{
  const std::string shape = r.text(n, f, "shape", "sphere", { "sphere", "square", "box", "cylinder" });
  s.shape = shape == "square"   ? SceneSphere::Shape::Square :
            shape == "box"      ? SceneSphere::Shape::Box :
            shape == "cylinder" ? SceneSphere::Shape::Cylinder :
                                  SceneSphere::Shape::Sphere;
  const bool box = s.shape == SceneSphere::Shape::Box, cylinder = s.shape == SceneSphere::Shape::Cylinder;
  auto only = [&](const char* key, bool allowed, const std::string& why) {
    if (!allowed && SceneReader::has(n, key))
      r.fail(SceneReader::join(f, key), why + " (this object is a " + shape + ")");
  };
  only("radius", !box, "not for a box: give its edge lengths as size [sx, sy, sz]");
  only("size", box, "only for shape box");
  only("height", cylinder, "only for shape cylinder");
  only("face_colours", box, "only for shape box");
  only("spin_axis", s.shape != SceneSphere::Shape::Square, "not for a square: it always faces the camera");
  only("yaw_deg", s.shape != SceneSphere::Shape::Square, "not for a square: it always faces the camera");
  if (box)
    s.size = rangedVec3(r, n, f, "size", nullptr, 1e-4, 100.0);
  else
    s.radius = r.number(n, f, "radius", s.radius, 1e-4, 100.0);
  if (cylinder)
    s.height = r.required(n, f, "height", 1e-4, 100.0);
}

// Face colours, texture seed and the turn (spin axis, initial yaw) of an object; after readShape() and
// the pattern.
void readLookAndTurn(const SceneReader& r, const cv::FileNode& n, const std::string& f, SceneSphere& s)
{
  if (SceneReader::has(n, "face_colours"))
  {
    const std::string field = f + ".face_colours";
    const cv::FileNode list = n["face_colours"];
    if (!list.isSeq() || list.size() != 6)
      r.fail(field, "must be a list of 6 RGB colours (faces +x, -x, +y, -y, +z, -z), got " +
                        SceneReader::describe(list));
    int i = 0;
    for (cv::FileNodeIterator it = list.begin(); it != list.end(); ++it, ++i)
    {
      const std::string element = field + "[" + std::to_string(i) + "]";
      const std::vector<double> v = r.numbers(*it, element, 3);
      for (double c : v)
        if (!(c >= 0.0 && c <= 255.0))
          r.fail(element, "RGB components must be in [0, 255]");
      s.face_colours.emplace_back(v[2], v[1], v[0]);
    }
  }
  if (SceneReader::has(n, "texture_seed") && !s.textured)
    r.fail(f + ".texture_seed", "only with pattern: texture");
  s.texture_seed = static_cast<uint64_t>(r.integer(n, f, "texture_seed", 1, 0, 2147483647));
  if (SceneReader::has(n, "spin_axis"))
  {
    s.spin_axis = rangedVec3(r, n, f, "spin_axis", nullptr, -1e3, 1e3);
    if (!(s.spin_axis.norm() > 1e-9))
      r.fail(f + ".spin_axis", "must not be zero (a direction [x, y, z]; y is down)");
  }
  s.yaw = deg2rad(r.number(n, f, "yaw_deg", 0.0, -3600.0, 3600.0));
}

std::string fileStem(const std::string& path)
{
  size_t slash = path.find_last_of('/');
  std::string base = slash == std::string::npos ? path : path.substr(slash + 1);
  const size_t dot = base.find_last_of('.');
  return dot == std::string::npos ? base : base.substr(0, dot);
}

}  // namespace

// --------------------------------------------------------------------------------------------------
// Trajectory

Eigen::Vector3d Trajectory::at(double t) const
{
  switch (type)
  {
    case Type::Static:
      return position;
    case Type::Waypoints:
    {
      if (points.empty())
        return position;
      if (t <= times.front())
        return points.front();
      if (t >= times.back())
        return points.back();
      const size_t i = std::upper_bound(times.begin(), times.end(), t) - times.begin();
      const double s = (t - times[i - 1]) / (times[i] - times[i - 1]);
      return points[i - 1] + s * (points[i] - points[i - 1]);
    }
    case Type::Pendulum:
    {
      const double angle = amplitude * std::cos(2.0 * kPi * t / period + phase);
      const Eigen::Vector3d swing(std::cos(plane_angle), 0.0, std::sin(plane_angle));
      return pivot + length * (std::sin(angle) * swing + std::cos(angle) * Eigen::Vector3d::UnitY());
    }
    case Type::Bounce:
    {
      const Eigen::Vector3d p = position + t * velocity;
      Eigen::Vector3d out;
      for (int a = 0; a < 3; ++a)
        out[a] = reflect(p[a], box_min[a], box_max[a]);
      return out;
    }
    case Type::Ballistic:
      return scene_detail::ballisticAt(*this, t);
    case Type::RandomWalk:
      return scene_detail::randomWalkAt(*this, t);
  }
  return position;
}

std::string Trajectory::validate() const
{
  if (!(t_leave > t_enter))
    return "t_leave must be after t_enter";
  switch (type)
  {
    case Type::Static:
      return position.allFinite() ? "" : "position must be finite";
    case Type::Waypoints:
      if (times.empty() || times.size() != points.size())
        return "waypoints need as many times as points (at least one)";
      for (size_t i = 1; i < times.size(); ++i)
        if (!(times[i] > times[i - 1]))
          return "waypoint times must be strictly increasing";
      return "";
    case Type::Pendulum:
      if (!(length > 0.0))
        return "pendulum length must be > 0";
      if (!(period > 0.0))
        return "pendulum period must be > 0";
      return "";
    case Type::Bounce:
      for (int a = 0; a < 3; ++a)
        if (!(box_max[a] > box_min[a]))
          return "bounce box_max must exceed box_min on every axis, got box_min " + vecText(box_min) + " box_max " +
                 vecText(box_max);
      return "";
    case Type::Ballistic:
      return scene_detail::validateBallistic(*this);
    case Type::RandomWalk:
      return scene_detail::validateRandomWalk(*this);
  }
  return "";
}

Trajectory Trajectory::fixed(const Eigen::Vector3d& p)
{
  Trajectory t;
  t.type = Type::Static;
  t.position = p;
  return t;
}

Trajectory Trajectory::linear(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double t_start, double t_end)
{
  Trajectory t;
  t.type = Type::Waypoints;
  t.times = { t_start, t_end };
  t.points = { a, b };
  t.position = a;
  return t;
}

Trajectory Trajectory::pendulum(const Eigen::Vector3d& pivot, double length, double amplitude, double period,
                                double phase, double plane_angle)
{
  Trajectory t;
  t.type = Type::Pendulum;
  t.pivot = pivot;
  t.length = length;
  t.amplitude = amplitude;
  t.period = period;
  t.phase = phase;
  t.plane_angle = plane_angle;
  return t;
}

Trajectory Trajectory::bounce(const Eigen::Vector3d& start, const Eigen::Vector3d& velocity,
                              const Eigen::Vector3d& box_min, const Eigen::Vector3d& box_max)
{
  Trajectory t;
  t.type = Type::Bounce;
  t.position = start;
  t.velocity = velocity;
  t.box_min = box_min;
  t.box_max = box_max;
  return t;
}

// --------------------------------------------------------------------------------------------------
// SceneDescription

StereoGeometry SceneDescription::geometry() const
{
  return StereoGeometry(camera.fx, camera.fy, camera.cx, camera.cy, camera.baseline, camera.width, camera.height);
}

std::string SceneDescription::validate() const
{
  std::ostringstream out;
  auto check = [&out](bool ok, const std::string& what) {
    if (!ok)
      out << what << "\n";
  };
  check(camera.width > 0 && camera.height > 0, "camera.width and camera.height must be > 0");
  check(camera.fx > 0.0 && camera.fy > 0.0, "camera.fx and camera.fy must be > 0");
  check(camera.baseline > 0.0, "camera.baseline must be > 0");
  check(fps > 0.0, "fps must be > 0");
  check(frames > 0, "frames must be > 0");
  check(target_roi_frame >= 0 && target_roi_frame < frames, "target_roi_frame must be in [0, frames)");
  check(noise_sigma >= 0.0, "noise.sigma must be >= 0");
  check(noise_shot >= 0.0 && noise_shot <= 10.0, "noise.shot must be in [0, 10]");
  check(camera.row_offset >= -5.0 && camera.row_offset <= 5.0, "camera.row_offset must be in [-5, 5]");
  const std::string sensor_problems = sensor.validate();
  check(sensor_problems.empty(), sensor_problems);
  // A camera cannot expose one frame for longer than the time between two frames.
  if (sensor.exposure > 1.0 / fps + 1e-12)
  {
    std::ostringstream s;
    s << "sensor.exposure must not exceed the frame period 1/fps = " << 1.0 / fps << " s, got " << sensor.exposure;
    check(false, s.str());
  }
  check(min_visible_fraction >= 0.0 && min_visible_fraction <= 1.0, "min_visible_fraction must be in [0, 1]");
  check(light.ambient >= 0.0 && light.ambient <= 1.0, "light.ambient must be in [0, 1]");
  check(light.direction.norm() > 1e-9, "light.direction must not be zero");
  check(background.depth > 0.0, "background.depth must be > 0");
  check(!objects.empty(), "objects: at least one (the target) is required");
  for (size_t i = 0; i < objects.size(); ++i)
  {
    const SceneSphere& s = objects[i];
    const std::string f = "objects[" + std::to_string(i) + "]";
    check(s.radius > 0.0, f + ".radius must be > 0");
    check(s.checker_longitude >= 1 && s.checker_latitude >= 1, f + ".checker_squares must be >= 1");
    check(!(s.checkered && s.textured), f + ".pattern: checker and texture at once");
    check(s.spin_axis.allFinite() && s.spin_axis.norm() > 1e-9, f + ".spin_axis must be a non-zero vector");
    if (s.shape == SceneSphere::Shape::Box)
    {
      check(s.size.allFinite() && (s.size.array() > 0.0).all(), f + ".size must be > 0 on every axis");
      check(s.face_colours.empty() || s.face_colours.size() == 6, f + ".face_colours must hold 6 colours");
    }
    if (s.shape == SceneSphere::Shape::Cylinder)
      check(s.height > 0.0, f + ".height must be > 0");
    const std::string t = s.trajectory.validate();
    check(t.empty(), f + ".trajectory: " + t);
  }
  for (size_t i = 0; i < occluders.size(); ++i)
  {
    const SceneOccluder& o = occluders[i];
    const std::string f = "occluders[" + std::to_string(i) + "]";
    check(o.width > 0.0 && o.height > 0.0, f + ".size must be > 0");
    const std::string t = o.trajectory.validate();
    check(t.empty(), f + ".trajectory: " + t);
  }
  std::string s = out.str();
  if (!s.empty())
    s.pop_back();
  return s;
}

// --------------------------------------------------------------------------------------------------
// Loading

SceneDescription loadScene(const std::string& path)
{
  std::ifstream in(path);
  if (!in)
    throw SceneError("cannot read scene '" + path + "': cannot open the file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  std::string text = buffer.str();
  // OpenCV's YAML reader insists on a "%YAML" directive: supply it so plain YAML files load too.
  if (text.compare(0, 5, "%YAML") != 0)
    text = "%YAML:1.0\n" + text;

  cv::FileStorage fs;
  try
  {
    fs.open(text, cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
  }
  catch (const cv::Exception& e)
  {
    // OpenCV puts "(line): message" into the function-name slot of parse errors.
    std::string where = e.func;
    if (!where.empty() && where.front() == '(')
    {
      const size_t close = where.find("):");
      int line = std::atoi(where.c_str() + 1);
      if (text.compare(0, 10, "%YAML:1.0\n") == 0 && buffer.str().compare(0, 5, "%YAML") != 0)
        --line;  // we added a line
      if (close != std::string::npos)
        where = "line " + std::to_string(line) + ":" + where.substr(close + 2);
    }
    throw SceneError("cannot read scene '" + path + "': YAML syntax error at " + where);
  }
  if (!fs.isOpened())
    throw SceneError("cannot read scene '" + path + "': not a readable YAML file");

  const SceneReader r(path);
  const cv::FileNode root = fs.root();
  r.checkKeys(root, "",
              { "name", "fps", "frames", "duration", "target_roi_frame", "min_visible_fraction", "camera", "light",
                "noise", "sensor", "background", "objects", "occluders" });

  SceneDescription d;
  d.source = path;
  d.name = r.text(root, "", "name", fileStem(path));
  d.fps = r.number(root, "", "fps", d.fps, 0.1, 10000.0);
  if (SceneReader::has(root, "frames") && SceneReader::has(root, "duration"))
    r.fail("duration", "give either frames or duration, not both");
  if (SceneReader::has(root, "duration"))
    d.frames = std::max(1, static_cast<int>(std::lround(r.required(root, "", "duration", 1e-6, 1e6) * d.fps)));
  else
    d.frames = r.integer(root, "", "frames", d.frames, 1, 10000000);
  d.target_roi_frame = r.integer(root, "", "target_roi_frame", 0, 0, d.frames - 1);
  d.min_visible_fraction = r.number(root, "", "min_visible_fraction", d.min_visible_fraction, 0.0, 1.0);
  const double duration = d.frames / d.fps;

  if (SceneReader::has(root, "camera"))
  {
    const cv::FileNode n = root["camera"];
    r.checkKeys(n, "camera", { "width", "height", "fx", "fy", "cx", "cy", "baseline", "row_offset" });
    SceneCamera& c = d.camera;
    c.width = r.integer(n, "camera", "width", c.width, 1, 100000);
    c.height = r.integer(n, "camera", "height", c.height, 1, 100000);
    c.fx = r.number(n, "camera", "fx", c.fx, 1e-3, 1e6);
    c.fy = r.number(n, "camera", "fy", c.fx, 1e-3, 1e6);
    c.cx = r.number(n, "camera", "cx", (c.width - 1) / 2.0, -1e6, 1e6);
    c.cy = r.number(n, "camera", "cy", (c.height - 1) / 2.0, -1e6, 1e6);
    c.baseline = r.number(n, "camera", "baseline", c.baseline, 1e-6, 100.0);
    c.row_offset = r.number(n, "camera", "row_offset", c.row_offset, -5.0, 5.0);
  }

  if (SceneReader::has(root, "light"))
  {
    const cv::FileNode n = root["light"];
    r.checkKeys(n, "light", { "direction", "ambient" });
    d.light.direction = r.vec3(n, "light", "direction", &d.light.direction);
    if (d.light.direction.norm() < 1e-9)
      r.fail("light.direction", "must not be zero");
    d.light.ambient = r.number(n, "light", "ambient", d.light.ambient, 0.0, 1.0);
  }

  if (SceneReader::has(root, "noise"))
  {
    const cv::FileNode n = root["noise"];
    r.checkKeys(n, "noise", { "sigma", "seed", "shot" });
    d.noise_sigma = r.number(n, "noise", "sigma", d.noise_sigma, 0.0, 255.0);
    d.noise_shot = r.number(n, "noise", "shot", d.noise_shot, 0.0, 10.0);
    d.seed = static_cast<uint64_t>(r.integer(n, "noise", "seed", 0, 0, 2147483647));
  }

  if (SceneReader::has(root, "sensor"))
  {
    const cv::FileNode n = root["sensor"];
    r.checkKeys(n, "sensor",
                { "exposure", "blur_samples", "vignetting", "gain_jitter", "right_gain", "right_gain_jitter",
                  "jpeg_quality", "encoding", "camera_info" });
    SceneSensor& s = d.sensor;
    s.exposure = r.number(n, "sensor", "exposure", s.exposure, 0.0, 1.0);
    s.blur_samples = r.integer(n, "sensor", "blur_samples", s.blur_samples, 0, 64);
    s.vignetting = r.number(n, "sensor", "vignetting", s.vignetting, 0.0, 0.9);
    s.gain_jitter = r.number(n, "sensor", "gain_jitter", s.gain_jitter, 0.0, 0.5);
    s.right_gain = r.number(n, "sensor", "right_gain", s.right_gain, 0.5, 2.0);
    s.right_gain_jitter = r.number(n, "sensor", "right_gain_jitter", s.right_gain_jitter, 0.0, 0.5);
    s.jpeg_quality = r.integer(n, "sensor", "jpeg_quality", s.jpeg_quality, 0, 100);
    const std::string encoding =
        r.text(n, "sensor", "encoding", "bgr8", { "bgr8", "rgb8", "mono8", "mono16", "bayer_grbg8" });
    encodingFromName(encoding, s.encoding);
    s.camera_info = r.text(n, "sensor", "camera_info", "full", { "full", "size_only" }) == "size_only" ?
                        SceneCameraInfo::SizeOnly :
                        SceneCameraInfo::Full;
  }

  if (SceneReader::has(root, "background"))
  {
    const cv::FileNode n = root["background"];
    r.checkKeys(n, "background",
                { "type", "colour", "depth", "rectangles", "blobs", "lines", "target_patches", "fine_noise", "seed" });
    SceneBackground& b = d.background;
    b.type = r.text(n, "background", "type", "plain", { "plain", "cluttered" }) == "cluttered" ?
                 SceneBackground::Type::Cluttered :
                 SceneBackground::Type::Plain;
    b.colour = r.colour(n, "background", "colour", b.colour);
    b.depth = r.number(n, "background", "depth", b.depth, 0.01, 1e4);
    b.rectangles = r.integer(n, "background", "rectangles", b.rectangles, 0, 100000);
    b.blobs = r.integer(n, "background", "blobs", b.blobs, 0, 100000);
    b.lines = r.integer(n, "background", "lines", b.lines, 0, 100000);
    b.target_patches = r.integer(n, "background", "target_patches", b.target_patches, 0, 100000);
    b.fine_noise = r.number(n, "background", "fine_noise", b.fine_noise, 0.0, 255.0);
    b.seed = static_cast<uint64_t>(r.integer(n, "background", "seed", 1, 0, 2147483647));
  }

  const cv::FileNode objects = root["objects"];
  if (objects.isNone() || !objects.isSeq() || objects.size() == 0)
    r.fail("objects", "must be a non-empty list of balls (the first one is the target)");
  int index = 0;
  for (cv::FileNodeIterator it = objects.begin(); it != objects.end(); ++it, ++index)
  {
    const cv::FileNode n = *it;
    const std::string f = "objects[" + std::to_string(index) + "]";
    r.checkKeys(n, f,
                { "name", "shape", "radius", "size", "height", "colour", "face_colours", "pattern", "colour2",
                  "checker_squares", "texture_seed", "spin_deg_per_s", "spin_axis", "yaw_deg", "string", "trajectory",
                  "t_enter", "t_leave" });
    SceneSphere s;
    s.name = r.text(n, f, "name", index == 0 ? "target" : "object" + std::to_string(index));
    readShape(r, n, f, s);
    s.colour = r.colour(n, f, "colour", s.colour);
    const std::string pattern = r.text(n, f, "pattern", "plain", { "plain", "checker", "texture" });
    s.checkered = pattern == "checker";
    s.textured = pattern == "texture";
    readLookAndTurn(r, n, f, s);
    s.colour2 = r.colour(n, f, "colour2", s.colour2);
    if (SceneReader::has(n, "checker_squares"))
    {
      const std::vector<double> q = r.numbers(n["checker_squares"], f + ".checker_squares", 2);
      if (q[0] < 1 || q[1] < 1 || q[0] != std::floor(q[0]) || q[1] != std::floor(q[1]))
        r.fail(f + ".checker_squares", "must be two positive integers [around, pole_to_pole]");
      s.checker_longitude = static_cast<int>(q[0]);
      s.checker_latitude = static_cast<int>(q[1]);
    }
    s.spin = deg2rad(r.number(n, f, "spin_deg_per_s", 0.0, -1e5, 1e5));
    s.trajectory = readTrajectory(r, n["trajectory"], f + ".trajectory", duration);
    s.draw_string = r.boolean(n, f, "string", false);
    if (s.draw_string && s.trajectory.type != Trajectory::Type::Pendulum)
      r.fail(f + ".string", "only pendulum trajectories have a string");
    readPresence(r, n, f, s.trajectory);
    d.objects.push_back(s);
  }

  const cv::FileNode occluders = root["occluders"];
  if (!occluders.isNone())
  {
    if (!occluders.isSeq())
      r.fail("occluders", "must be a list");
    index = 0;
    for (cv::FileNodeIterator it = occluders.begin(); it != occluders.end(); ++it, ++index)
    {
      const cv::FileNode n = *it;
      const std::string f = "occluders[" + std::to_string(index) + "]";
      r.checkKeys(n, f, { "name", "size", "colour", "trajectory", "t_enter", "t_leave" });
      SceneOccluder o;
      o.name = r.text(n, f, "name", "occluder" + std::to_string(index));
      const cv::FileNode size = n["size"];
      if (size.isNone())
        r.fail(f + ".size", "missing (required; [width, height] in metres)");
      const std::vector<double> wh = r.numbers(size, f + ".size", 2);
      if (!(wh[0] > 0.0 && wh[1] > 0.0))
        r.fail(f + ".size", "width and height must be > 0");
      o.width = wh[0];
      o.height = wh[1];
      o.colour = r.colour(n, f, "colour", o.colour);
      o.trajectory = readTrajectory(r, n["trajectory"], f + ".trajectory", duration);
      readPresence(r, n, f, o.trajectory);
      d.occluders.push_back(o);
    }
  }

  const std::string problems = d.validate();
  if (!problems.empty())
    throw SceneError("cannot read scene '" + path + "': " + problems);
  return d;
}

// --------------------------------------------------------------------------------------------------
// Rendering

namespace
{
// Validate before any member is built from the description (the sensor model sizes buffers from it).
const SceneDescription& checked(const SceneDescription& scene)
{
  const std::string problems = scene.validate();
  if (!problems.empty())
    throw SceneError("scene '" + scene.name + "' cannot be rendered: " + problems);
  return scene;
}
}  // namespace

SceneRenderer::SceneRenderer(const SceneDescription& scene)
  : scene_(checked(scene))
  , sensor_(scene.sensor, scene.noise_sigma, scene.noise_shot, scene.seed,
            cv::Size(scene.camera.width, scene.camera.height), scene.camera.cx, scene.camera.cy)
{
  // Rays through row v - row_offset of the ideal right camera put its content row_offset rows lower.
  imaging_[0] = imaging_[1] = scene_.camera;
  imaging_[1].cy += scene_.camera.row_offset;
  light_ = scene_.light.direction.normalized();
  renderBackdrop();
}

Eigen::Vector3d SceneRenderer::cameraOrigin(View view) const
{
  return view == View::Left ? Eigen::Vector3d::Zero() : Eigen::Vector3d(scene_.camera.baseline, 0.0, 0.0);
}

void SceneRenderer::renderBackdrop()
{
  const SceneCamera& cam = scene_.camera;
  const SceneBackground& bg = scene_.background;
  const double depth = bg.depth;
  for (int v = 0; v < 2; ++v)
  {
    backdrop_depth_[v].create(cam.height, cam.width, CV_32F);
    backdrop_depth_[v].setTo(cv::Scalar(depth));
    backdrop_[v].create(cam.height, cam.width, CV_8UC3);
    backdrop_[v].setTo(cv::Scalar(bg.colour[0], bg.colour[1], bg.colour[2]));
  }
  if (bg.type != SceneBackground::Type::Cluttered)
    return;

  // The clutter is painted once on the plane itself (texels of half a pixel's footprint) so that both
  // cameras see the same surface, with the disparity of the plane, and then resampled per camera.
  const double texel = depth / std::max(cam.fx, cam.fy) / 2.0;
  const double margin = 8.0 * texel;
  const double x_min = (-0.5 - cam.cx) / cam.fx * depth - margin;
  const double x_max = (cam.width - 0.5 - cam.cx) / cam.fx * depth + cam.baseline + margin;
  const double y_min = (-0.5 - cam.cy) / cam.fy * depth - margin;
  const double y_max = (cam.height - 0.5 - cam.cy) / cam.fy * depth + margin;
  const int tw = static_cast<int>(std::ceil((x_max - x_min) / texel)) + 1;
  const int th = static_cast<int>(std::ceil((y_max - y_min) / texel)) + 1;
  const double metres = 1.0 / texel;  // texels per metre

  cv::RNG rng(scene_detail::mix64(bg.seed));
  const cv::Vec3d mean = bg.colour;
  auto randomColour = [&rng, &mean]() {
    // Half fully random colours, half variations of the mean tone: busy but not a rainbow.
    if (rng.uniform(0.0, 1.0) < 0.5)
      return cv::Scalar(rng.uniform(0.0, 255.0), rng.uniform(0.0, 255.0), rng.uniform(0.0, 255.0));
    const double k = rng.uniform(0.5, 1.2);
    return cv::Scalar(std::min(255.0, mean[0] * k + rng.uniform(-30.0, 30.0)),
                      std::min(255.0, mean[1] * k + rng.uniform(-30.0, 30.0)),
                      std::min(255.0, mean[2] * k + rng.uniform(-30.0, 30.0)));
  };

  // Smooth shading and colour variations ("gradient noise"): random brightness and a little tint on a
  // coarse grid, interpolated bicubically.
  const int gw = std::max(2, static_cast<int>((x_max - x_min) / 0.3));
  const int gh = std::max(2, static_cast<int>((y_max - y_min) / 0.3));
  cv::Mat coarse(gh, gw, CV_32FC3);
  for (int i = 0; i < gh; ++i)
    for (int j = 0; j < gw; ++j)
    {
      const double bright = rng.uniform(-45.0, 45.0);
      coarse.at<cv::Vec3f>(i, j) = cv::Vec3f(static_cast<float>(mean[0] + bright + rng.uniform(-20.0, 20.0)),
                                             static_cast<float>(mean[1] + bright + rng.uniform(-20.0, 20.0)),
                                             static_cast<float>(mean[2] + bright + rng.uniform(-20.0, 20.0)));
    }
  cv::Mat smooth, texture;
  cv::resize(coarse, smooth, cv::Size(tw, th), 0, 0, cv::INTER_CUBIC);
  smooth.convertTo(texture, CV_8UC3);

  // Shapes in a random order so the target-coloured patches are sometimes partly covered too.
  std::vector<int> order;
  order.insert(order.end(), bg.rectangles, 0);
  order.insert(order.end(), bg.blobs, 1);
  order.insert(order.end(), bg.lines, 2);
  order.insert(order.end(), bg.target_patches, 3);
  for (size_t i = order.size(); i > 1; --i)
    std::swap(order[i - 1], order[static_cast<size_t>(rng.uniform(0, static_cast<int>(i)))]);

  const cv::Vec3d target = scene_.objects.front().colour;
  for (int kind : order)
  {
    const cv::Point2f centre(static_cast<float>(rng.uniform(0.0, static_cast<double>(tw))),
                             static_cast<float>(rng.uniform(0.0, static_cast<double>(th))));
    if (kind == 0 || kind == 3)
    {
      // Rectangles 3..35 cm, a third rotated, a quarter outlined; target patches 4..20 cm, half of them
      // elongated ellipses.
      const bool patch = kind == 3;
      const double lo = patch ? 0.04 : 0.03, hi = patch ? 0.20 : 0.35;
      const cv::Size2f size(static_cast<float>(rng.uniform(lo, hi) * metres),
                            static_cast<float>(rng.uniform(lo, hi) * metres));
      const float angle = rng.uniform(0.0, 1.0) < 0.33 ? static_cast<float>(rng.uniform(0.0, 180.0)) : 0.0f;
      cv::Scalar colour;
      if (patch)
      {
        const double k = rng.uniform(0.65, 1.0);  // shades of the target colour, like the ball's own shading
        colour = cv::Scalar(std::min(255.0, target[0] * k + rng.uniform(-8.0, 8.0)),
                            std::min(255.0, target[1] * k + rng.uniform(-8.0, 8.0)),
                            std::min(255.0, target[2] * k + rng.uniform(-8.0, 8.0)));
      }
      else
      {
        colour = randomColour();
      }
      if (patch && rng.uniform(0.0, 1.0) < 0.5)
      {
        // Elongated blobs only: a round target-coloured disc would be indistinguishable from the ball.
        const cv::Size2f elongated(size.width, size.width * static_cast<float>(rng.uniform(0.25, 0.5)));
        cv::ellipse(texture, cv::RotatedRect(centre, elongated, static_cast<float>(rng.uniform(0.0, 180.0))), colour,
                    cv::FILLED, cv::LINE_AA);
        continue;
      }
      cv::Point2f corners[4];
      cv::RotatedRect(centre, size, angle).points(corners);
      std::vector<cv::Point> poly(corners, corners + 4);
      if (!patch && rng.uniform(0.0, 1.0) < 0.25)
        cv::polylines(texture, poly, true, colour, rng.uniform(2, 8), cv::LINE_AA);
      else
        cv::fillConvexPoly(texture, poly, colour, cv::LINE_AA);
    }
    else if (kind == 1)
    {
      const cv::Size2f axes(static_cast<float>(rng.uniform(0.02, 0.15) * metres),
                            static_cast<float>(rng.uniform(0.02, 0.15) * metres));
      cv::ellipse(texture, cv::RotatedRect(centre, axes, static_cast<float>(rng.uniform(0.0, 180.0))), randomColour(),
                  cv::FILLED, cv::LINE_AA);
    }
    else
    {
      const double len = rng.uniform(0.1, 0.6) * metres, ang = rng.uniform(0.0, kPi);
      const cv::Point2f dir(static_cast<float>(std::cos(ang) * len / 2), static_cast<float>(std::sin(ang) * len / 2));
      cv::line(texture, centre - dir, centre + dir, randomColour(), rng.uniform(1, 9), cv::LINE_AA);
    }
  }

  // Fine grain (fabric/paper texture) so the texture model sees edges everywhere, not only at shapes.
  if (bg.fine_noise > 0.0)
  {
    cv::Mat grain(th, tw, CV_16SC3);
    rng.fill(grain, cv::RNG::NORMAL, cv::Scalar::all(0), cv::Scalar::all(bg.fine_noise * 2.0));
    cv::GaussianBlur(grain, grain, cv::Size(0, 0), 1.2);
    cv::add(texture, grain, texture, cv::noArray(), CV_8U);
  }
  // Half-pixel blur against aliasing when the texture is resampled at pixel rate.
  cv::GaussianBlur(texture, texture, cv::Size(0, 0), 0.8);

  for (int v = 0; v < 2; ++v)
  {
    const double ox = v == 0 ? 0.0 : cam.baseline;
    const double cy = imaging_[v].cy;  // the right camera's rows may be offset (camera.row_offset)
    cv::Mat map_x(cam.height, cam.width, CV_32F), map_y(cam.height, cam.width, CV_32F);
    for (int row = 0; row < cam.height; ++row)
    {
      const float ty = static_cast<float>(((row - cy) / cam.fy * depth - y_min) / texel);
      float* mx = map_x.ptr<float>(row);
      float* my = map_y.ptr<float>(row);
      for (int col = 0; col < cam.width; ++col)
      {
        mx[col] = static_cast<float>((ox + (col - cam.cx) / cam.fx * depth - x_min) / texel);
        my[col] = ty;
      }
    }
    cv::remap(texture, backdrop_[v], map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REFLECT);
  }
}

void SceneRenderer::render(int k, cv::Mat& left_bgr, cv::Mat& right_bgr, bool with_noise)
{
  renderView(k, View::Left, left_bgr, with_noise);
  renderView(k, View::Right, right_bgr, with_noise);
}

StereoFrame SceneRenderer::renderFrame(int k, cv::Mat& left_bgr, cv::Mat& right_bgr, bool with_noise)
{
  render(k, left_bgr, right_bgr, with_noise);
  StereoFrame frame;
  frame.left = left_bgr;
  frame.right = right_bgr;
  frame.stamp = stamp(k);
  frame.geometry = geometry();
  return frame;
}

void SceneRenderer::drawScene(double t, View view, cv::Mat& bgr)
{
  const int v = static_cast<int>(view);
  backdrop_[v].copyTo(bgr);
  backdrop_depth_[v].copyTo(depth_);
  drawOccluders(t, view, bgr, depth_);
  for (const SceneSphere& s : scene_.objects)
  {
    if (!s.trajectory.present(t))
      continue;
    if (s.shape == SceneSphere::Shape::Square)
      drawSquare(s, t, view, bgr, depth_);
    else if (isSolid(s))
      drawSolid(s, t, view, bgr, depth_);
    else
      drawSphere(s, t, view, bgr, depth_);
  }
  // Strings after the balls so the depth test hides the part inside the ball.
  for (const SceneSphere& s : scene_.objects)
    if (s.draw_string && s.trajectory.present(t))
      drawString(s, t, view, bgr, depth_);
}

void SceneRenderer::drawOccluders(double t, View view, cv::Mat& img, cv::Mat& depth) const
{
  const SceneCamera& cam = imagingCamera(view);
  const Eigen::Vector3d origin = cameraOrigin(view);
  for (const SceneOccluder& o : scene_.occluders)
  {
    if (!o.trajectory.present(t))
      continue;
    const Eigen::Vector3d c = o.trajectory.at(t) - origin;
    const double z = c.z();
    if (z <= 1e-3)
      continue;
    // A board facing the camera projects to an axis-aligned rectangle at constant depth; edge pixels
    // get their area coverage as alpha (cheap anti-aliasing).
    const double ul = cam.cx + cam.fx * (c.x() - o.width / 2) / z, ur = cam.cx + cam.fx * (c.x() + o.width / 2) / z;
    const double vt = cam.cy + cam.fy * (c.y() - o.height / 2) / z, vb = cam.cy + cam.fy * (c.y() + o.height / 2) / z;
    const int u0 = std::max(0, static_cast<int>(std::floor(ul)));
    const int u1 = std::min(cam.width - 1, static_cast<int>(std::ceil(ur)));
    const int v0 = std::max(0, static_cast<int>(std::floor(vt)));
    const int v1 = std::min(cam.height - 1, static_cast<int>(std::ceil(vb)));
    const float zf = static_cast<float>(z);
    for (int row = v0; row <= v1; ++row)
    {
      const double ay = std::clamp(std::min(row + 0.5, vb) - std::max(row - 0.5, vt), 0.0, 1.0);
      if (ay <= 0.0)
        continue;
      cv::Vec3b* px = img.ptr<cv::Vec3b>(row);
      float* dp = depth.ptr<float>(row);
      for (int col = u0; col <= u1; ++col)
      {
        const double a = ay * std::clamp(std::min(col + 0.5, ur) - std::max(col - 0.5, ul), 0.0, 1.0);
        if (a <= 0.0 || zf >= dp[col])
          continue;
        for (int ch = 0; ch < 3; ++ch)
          px[col][ch] = cv::saturate_cast<uint8_t>(a * o.colour[ch] + (1.0 - a) * px[col][ch]);
        if (a >= 0.5)
          dp[col] = zf;
      }
    }
  }
}

void SceneRenderer::drawSphere(const SceneSphere& s, double t, View view, cv::Mat& img, cv::Mat& depth) const
{
  const SceneCamera& cam = imagingCamera(view);
  const Eigen::Vector3d centre = s.trajectory.at(t);
  const Eigen::Vector3d origin = cameraOrigin(view);
  const Eigen::Vector3d c = centre - origin;  // centre seen from this camera
  PixelBox box;
  if (!sphereBox(cam, c, s.radius, box))
    return;
  // Only pixels in the silhouette's bounding box (plus one for the anti-aliased rim) cast rays.
  const int u0 = std::max(0, static_cast<int>(std::floor(box.u0)) - 1);
  const int u1 = std::min(cam.width - 1, static_cast<int>(std::ceil(box.u1)) + 1);
  const int v0 = std::max(0, static_cast<int>(std::floor(box.v0)) - 1);
  const int v1 = std::min(cam.height - 1, static_cast<int>(std::ceil(box.v1)) + 1);
  if (u0 > u1 || v0 > v1)
    return;

  const double r = s.radius, r2 = r * r, c2 = c.squaredNorm();
  const double ambient = scene_.light.ambient;
  const double spin = s.spin * t + s.yaw;
  // Patterns turning about the vertical axis keep the longitude shift below; any other axis, and the
  // texture, read the surface point in the ball's own frame.
  const bool upright = s.spin_axis.x() == 0.0 && s.spin_axis.z() == 0.0 && s.spin_axis.y() > 0.0;
  const Eigen::Matrix3d to_ball = s.orientation(t).transpose();
  std::optional<scene_detail::TextureField> texture;
  if (s.textured)
    texture.emplace(s);
  for (int row = v0; row <= v1; ++row)
  {
    const double b = (row - cam.cy) / cam.fy;
    cv::Vec3b* px = img.ptr<cv::Vec3b>(row);
    float* dp = depth.ptr<float>(row);
    for (int col = u0; col <= u1; ++col)
    {
      const Eigen::Vector3d d((col - cam.cx) / cam.fx, b, 1.0);  // ray direction; t along it equals depth z
      const double dd = d.squaredNorm();
      const double proj = d.dot(c) / dd;  // ray parameter of closest approach to the centre
      const double perp = std::sqrt(std::max(0.0, c2 - proj * proj * dd));
      // Coverage of the rim: distance to the silhouette in units of one pixel's footprint at that depth.
      const double alpha = std::clamp(0.5 + (r - perp) / (proj * std::sqrt(dd) / cam.fx), 0.0, 1.0);
      if (alpha <= 0.0)
        continue;
      Eigen::Vector3d hit;  // relative to this camera
      if (perp < r)
        hit = (proj - std::sqrt((r2 - perp * perp) / dd)) * d;
      else
        hit = c + r * (proj * d - c).normalized();  // rim pixel whose centre misses: shade the silhouette point
      const float z = static_cast<float>(hit.z());
      if (z >= dp[col])
        continue;
      const Eigen::Vector3d n = (hit - c) / r;
      cv::Vec3d albedo = s.colour;
      if (s.checkered)
      {
        // Longitude around the vertical axis (0 facing the camera), latitude from the -y (up) pole.
        const Eigen::Vector3d m = upright ? n : Eigen::Vector3d(to_ball * n);
        const double lon = std::atan2(m.x(), -m.z()) + (upright ? spin : 0.0);
        const double lat = std::asin(std::clamp(-m.y(), -1.0, 1.0));
        const long i = static_cast<long>(std::floor(lon / (2.0 * kPi) * s.checker_longitude));
        const long j = static_cast<long>(std::floor((lat + kPi / 2) / kPi * s.checker_latitude));
        if (((i + j) % 2 + 2) % 2 == 1)
          albedo = s.colour2;
      }
      else if (texture)
      {
        albedo = texture->mix(albedo, to_ball * n);
      }
      const double shade = ambient + (1.0 - ambient) * std::max(0.0, n.dot(light_));
      for (int ch = 0; ch < 3; ++ch)
        px[col][ch] = cv::saturate_cast<uint8_t>(alpha * shade * albedo[ch] + (1.0 - alpha) * px[col][ch]);
      if (alpha >= 0.5)
        dp[col] = z;
    }
  }
}

void SceneRenderer::drawSquare(const SceneSphere& s, double t, View view, cv::Mat& img, cv::Mat& depth) const
{
  const SceneCamera& cam = imagingCamera(view);
  const Eigen::Vector3d c = s.trajectory.at(t) - cameraOrigin(view);
  PixelBox box;
  if (!squareBox(cam, c, s.radius, box))
    return;
  const int u0 = std::max(0, static_cast<int>(std::floor(box.u0)));
  const int u1 = std::min(cam.width - 1, static_cast<int>(std::ceil(box.u1)));
  const int v0 = std::max(0, static_cast<int>(std::floor(box.v0)));
  const int v1 = std::min(cam.height - 1, static_cast<int>(std::ceil(box.v1)));
  const double z = c.z();
  const float zf = static_cast<float>(z);
  // A flat face has one normal (-z), so one Lambertian shade for the whole patch.
  const double shade = scene_.light.ambient + (1.0 - scene_.light.ambient) * std::max(0.0, -light_.z());
  const double side = 2.0 * s.radius;
  std::optional<scene_detail::TextureField> texture;
  if (s.textured)
    texture.emplace(s);
  for (int row = v0; row <= v1; ++row)
  {
    // Edge pixels get their area coverage as alpha, as the occluders do.
    const double ay = std::clamp(std::min(row + 0.5, box.v1) - std::max(row - 0.5, box.v0), 0.0, 1.0);
    if (ay <= 0.0)
      continue;
    // Pattern coordinates of the pixel centre on the patch, in [0, 1) from its top-left corner.
    const double py = ((row - cam.cy) / cam.fy * z - c.y() + s.radius) / side;
    const long j = static_cast<long>(std::floor(std::clamp(py, 0.0, 0.999999) * s.checker_latitude));
    cv::Vec3b* px = img.ptr<cv::Vec3b>(row);
    float* dp = depth.ptr<float>(row);
    for (int col = u0; col <= u1; ++col)
    {
      const double a = ay * std::clamp(std::min(col + 0.5, box.u1) - std::max(col - 0.5, box.u0), 0.0, 1.0);
      if (a <= 0.0 || zf >= dp[col])
        continue;
      cv::Vec3d albedo = s.colour;
      if (s.checkered)
      {
        const double pxl = ((col - cam.cx) / cam.fx * z - c.x() + s.radius) / side;
        const long i = static_cast<long>(std::floor(std::clamp(pxl, 0.0, 0.999999) * s.checker_longitude));
        if ((i + j) % 2 == 1)
          albedo = s.colour2;
      }
      else if (texture)
      {
        // The patch's own coordinates in half sides (the square does not turn).
        const Eigen::Vector3d q(((col - cam.cx) / cam.fx * z - c.x()) / s.radius,
                                ((row - cam.cy) / cam.fy * z - c.y()) / s.radius, 0.0);
        albedo = texture->mix(albedo, q);
      }
      for (int ch = 0; ch < 3; ++ch)
        px[col][ch] = cv::saturate_cast<uint8_t>(a * shade * albedo[ch] + (1.0 - a) * px[col][ch]);
      if (a >= 0.5)
        dp[col] = zf;
    }
  }
}

void SceneRenderer::drawString(const SceneSphere& s, double t, View view, cv::Mat& img, const cv::Mat& depth) const
{
  if (s.trajectory.type != Trajectory::Type::Pendulum)
    return;
  const SceneCamera& cam = imagingCamera(view);
  const Eigen::Vector3d origin = cameraOrigin(view);
  const Eigen::Vector3d a = s.trajectory.pivot - origin;
  const Eigen::Vector3d b = s.trajectory.at(t) - origin;
  if (a.z() <= 1e-3 || b.z() <= 1e-3)
    return;
  // Sample the 3D segment at about half-pixel spacing in the image; each sample is depth tested, so
  // the string disappears behind occluders and inside the ball.
  const double du = cam.fx * (a.x() / a.z() - b.x() / b.z()), dv = cam.fy * (a.y() / a.z() - b.y() / b.z());
  const int n = std::min(20000, static_cast<int>(2.0 * std::hypot(du, dv)) + 2);
  const cv::Vec3b dark(45, 45, 50);
  for (int i = 0; i < n; ++i)
  {
    const Eigen::Vector3d p = a + (b - a) * (static_cast<double>(i) / (n - 1));
    const int col = static_cast<int>(std::lround(cam.cx + cam.fx * p.x() / p.z()));
    const int row = static_cast<int>(std::lround(cam.cy + cam.fy * p.y() / p.z()));
    if (col < 0 || row < 0 || col >= cam.width || row >= cam.height)
      continue;
    if (static_cast<float>(p.z()) < depth.at<float>(row, col))
      img.at<cv::Vec3b>(row, col) = dark;
  }
}

// --------------------------------------------------------------------------------------------------
// Ground truth

Eigen::Vector3d SceneRenderer::objectPosition(size_t i, int k) const
{
  return scene_.objects.at(i).trajectory.at(stamp(k));
}

bool SceneRenderer::objectPresent(size_t i, int k) const
{
  return scene_.objects.at(i).trajectory.present(stamp(k));
}

double SceneRenderer::nearestOtherHit(size_t i, double t, const Eigen::Vector3d& origin,
                                      const Eigen::Vector3d& dir) const
{
  double best = scene_.background.depth / dir.z();
  for (size_t j = 0; j < scene_.objects.size(); ++j)
  {
    const SceneSphere& s = scene_.objects[j];
    if (j != i && s.trajectory.present(t))
      best = std::min(best, rayObject(origin, dir, s, s.trajectory.at(t), t));
  }
  for (const SceneOccluder& o : scene_.occluders)
  {
    if (!o.trajectory.present(t))
      continue;
    const Eigen::Vector3d c = o.trajectory.at(t);
    const double tp = (c.z() - origin.z()) / dir.z();
    if (tp <= 0.0)
      continue;
    const Eigen::Vector3d p = origin + tp * dir;
    if (std::abs(p.x() - c.x()) <= o.width / 2 && std::abs(p.y() - c.y()) <= o.height / 2)
      best = std::min(best, tp);
  }
  return best;
}

double SceneRenderer::visibleFraction(size_t i, int k, View view) const
{
  const SceneSphere& s = scene_.objects.at(i);
  const double t = stamp(k);
  if (!s.trajectory.present(t))
    return 0.0;
  const SceneCamera& cam = scene_.camera;
  const Eigen::Vector3d origin = cameraOrigin(view);
  const Eigen::Vector3d centre = s.trajectory.at(t);
  PixelBox box;
  if (!objectBox(cam, s, centre - origin, t, box))
    return 0.0;
  // Sample the silhouette on a grid of at most ~48 x 48 rays: plenty for a 50 % decision.
  const double step = std::max(1.0, std::max(box.u1 - box.u0, box.v1 - box.v0) / 48.0);
  int total = 0, shown = 0;
  for (double v = box.v0 + step / 2; v < box.v1; v += step)
  {
    for (double u = box.u0 + step / 2; u < box.u1; u += step)
    {
      const Eigen::Vector3d dir((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0);
      const double hit = rayObject(origin, dir, s, centre, t);
      if (!std::isfinite(hit))
        continue;
      ++total;
      const bool in_image = u >= -0.5 && v >= -0.5 && u < cam.width - 0.5 && v < cam.height - 0.5;
      if (in_image && hit < nearestOtherHit(i, t, origin, dir))
        ++shown;
    }
  }
  return total > 0 ? static_cast<double>(shown) / total : 0.0;
}

cv::Rect SceneRenderer::objectRoi(size_t i, int k, View view) const
{
  const SceneSphere& s = scene_.objects.at(i);
  const double t = stamp(k);
  if (!s.trajectory.present(t))
    return cv::Rect();
  PixelBox box;
  if (!objectBox(scene_.camera, s, s.trajectory.at(t) - cameraOrigin(view), t, box))
    return cv::Rect();
  // Pixels whose centres lie inside the silhouette's extent.
  const int x0 = static_cast<int>(std::ceil(box.u0)), x1 = static_cast<int>(std::floor(box.u1));
  const int y0 = static_cast<int>(std::ceil(box.v0)), y1 = static_cast<int>(std::floor(box.v1));
  if (x1 < x0 || y1 < y0)
    return cv::Rect();
  return cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1) & cv::Rect(0, 0, scene_.camera.width, scene_.camera.height);
}

bool SceneRenderer::targetVisible(int k) const
{
  return objectPresent(0, k) && visibleFraction(0, k, View::Left) >= scene_.min_visible_fraction &&
         visibleFraction(0, k, View::Right) >= scene_.min_visible_fraction;
}

}  // namespace stereo_pf
