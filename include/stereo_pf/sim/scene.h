// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Synthetic stereo scenes: a YAML description (camera, shaded balls, square patches, boxes and cylinders on
// trajectories, background, occluders, sensor noise) and a ray-casting renderer of the rectified pair with
// ground truth.
// ROS-free; the `make_scene` tool writes the result into a bag.
#pragma once

#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "stereo_pf/sim/scene_sensor.h"
#include "stereo_pf/core/stereo_frame.h"
#include "stereo_pf/core/stereo_geometry.h"

namespace stereo_pf
{
/// Thrown by loadScene() and SceneDescription checks; what() names the file and the field.
class SceneError : public std::runtime_error
{
public:
  using std::runtime_error::runtime_error;
};

/// Ideal rectified stereo camera of a scene: both cameras share the intrinsics; the left camera is at
/// the origin, the right one at (+baseline, 0, 0); both look down +z (x right, y down).
struct SceneCamera
{
  int width = 640;          ///< image width, pixels
  int height = 480;         ///< image height, pixels
  double fx = 525.0;        ///< focal length along x, pixels
  double fy = 525.0;        ///< focal length along y, pixels
  double cx = 319.5;        ///< principal point column; loadScene() defaults it to the image centre (width - 1) / 2
  double cy = 239.5;        ///< principal point row; loadScene() defaults it to the image centre (height - 1) / 2
  double baseline = 0.09;   ///< distance between the optical centres, metres
  /// Rectification residual, pixels, [-5, 5]: the right image's content sits this many rows lower than
  /// the ideal rectified pair puts it (the calibration and ground truth stay the ideal ones).
  double row_offset = 0.0;
};

/// Where an object is over time, and when it exists at all. Positions are in the left optical frame
/// (metres); time is seconds since the first frame. Build one with the factory functions.
struct Trajectory
{
  /// Kind of motion.
  enum class Type
  {
    Static,     ///< fixed at `position`
    Waypoints,  ///< piecewise linear through `points` at `times`, clamped before/after ("linear" is two waypoints)
    Pendulum,   ///< bob of a pendulum hanging from `pivot`
    Bounce,     ///< straight lines at constant `velocity`, reflected at the walls of [box_min, box_max]
    Ballistic,  ///< thrown from `position` with `velocity` at `t0` under `gravity`, optionally bouncing off a floor
    RandomWalk  ///< smooth seeded wandering of typical speed `speed` inside `position` +- `extent`
  };

  Type type = Type::Static;  ///< kind of motion
  /// Static: the position; Bounce: position at t = 0; Ballistic: start (until t0); RandomWalk: centre of its box
  Eigen::Vector3d position = Eigen::Vector3d(0.0, 0.0, 1.0);

  std::vector<double> times;                 ///< Waypoints: strictly increasing times, seconds
  std::vector<Eigen::Vector3d> points;       ///< Waypoints: positions at `times`

  Eigen::Vector3d pivot = Eigen::Vector3d(0.0, -0.85, 1.1);  ///< Pendulum: suspension point
  double length = 1.0;       ///< Pendulum: string length (pivot to centre), metres
  double amplitude = 0.45;   ///< Pendulum: swing amplitude, radians
  double period = 2.0;       ///< Pendulum: period of a full swing, seconds
  double phase = 0.0;        ///< Pendulum: angle = amplitude * cos(2 pi t / period + phase), radians
  double plane_angle = 0.0;  ///< Pendulum: swing plane rotated about the vertical (y) axis, radians;
                             ///< 0 swings along x only, > 0 also moves the bob in depth (+z when x > 0)

  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();     ///< Bounce: velocity; Ballistic: launch velocity, m/s
  Eigen::Vector3d box_min = Eigen::Vector3d(-0.3, -0.2, 0.8);  ///< Bounce: lower corner of the box the centre stays in
  Eigen::Vector3d box_max = Eigen::Vector3d(0.3, 0.2, 1.4);    ///< Bounce: upper corner of the box the centre stays in

  Eigen::Vector3d gravity = Eigen::Vector3d(0.0, 9.81, 0.0);  ///< Ballistic: acceleration, m/s^2 (y is down)
  double t0 = 0.0;            ///< Ballistic: launch time, seconds (at `position` before it)
  bool has_floor = false;     ///< Ballistic: bounce off the plane y = floor_y
  double floor_y = 0.0;       ///< Ballistic: the floor plane (the centre never goes below it, i.e. y <= floor_y)
  double restitution = 0.7;   ///< Ballistic: speed kept across the floor (normal component), [0, 1]

  Eigen::Vector3d extent = Eigen::Vector3d(0.2, 0.1, 0.1);  ///< RandomWalk: half sizes of the box the centre stays in
  double speed = 0.3;         ///< RandomWalk: root-mean-square speed over a long run, m/s
  uint64_t seed = 1;          ///< RandomWalk: path seed (same seed, same path)

  double t_enter = -std::numeric_limits<double>::infinity();  ///< the object exists from this time on
  double t_leave = std::numeric_limits<double>::infinity();   ///< ... until this time (exclusive)

  /// Position at time t (defined even when the object is not present).
  Eigen::Vector3d at(double t) const;
  /// True when the object exists at time t (t_enter <= t < t_leave).
  bool present(double t) const { return t >= t_enter && t < t_leave; }
  /// Empty when usable, otherwise what is wrong (e.g. "length must be > 0").
  std::string validate() const;

  /// Fixed position.
  static Trajectory fixed(const Eigen::Vector3d& p);
  /// From a (at t_start and before) to b (at t_end and after) at constant speed.
  static Trajectory linear(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double t_start, double t_end);
  /// Pendulum (angles in radians).
  static Trajectory pendulum(const Eigen::Vector3d& pivot, double length, double amplitude, double period,
                             double phase = 0.0, double plane_angle = 0.0);
  /// Bouncing inside a box.
  static Trajectory bounce(const Eigen::Vector3d& start, const Eigen::Vector3d& velocity,
                           const Eigen::Vector3d& box_min, const Eigen::Vector3d& box_max);
  /// Thrown from `start` with `velocity` at time t0 under `gravity` (no floor; set has_floor/floor_y for one).
  static Trajectory ballistic(const Eigen::Vector3d& start, const Eigen::Vector3d& velocity,
                              const Eigen::Vector3d& gravity = Eigen::Vector3d(0.0, 9.81, 0.0), double t0 = 0.0);
  /// Smooth seeded wandering inside centre +- extent with root-mean-square speed `speed`.
  static Trajectory randomWalk(const Eigen::Vector3d& centre, const Eigen::Vector3d& extent, double speed,
                               uint64_t seed);
};

/// A scene object: a shaded ball, a flat square patch facing the camera, a box or a cylinder. The first one
/// of a scene is the tracking target. Balls, boxes and cylinders turn about `spin_axis` (object frame ->
/// camera frame: a rotation by yaw + spin * t about that axis); squares always face the camera.
struct SceneSphere
{
  /// Geometry of the object.
  enum class Shape
  {
    Sphere,  ///< a ball of `radius`
    Square,  ///< a flat square facing the camera (normal along -z), side 2 * `radius`, edges along x and y
    Box,     ///< a box of edge lengths `size` along its own x, y, z (unturned: faces along the camera's axes)
    Cylinder ///< a cylinder of `radius` and `height` whose axis is its own y axis (vertical when unturned)
  };

  std::string name;                           ///< label (for messages)
  Shape shape = Shape::Sphere;                ///< geometry
  double radius = 0.035;                      ///< metres (a square's half side; a cylinder's radius; unused by boxes)
  Eigen::Vector3d size = Eigen::Vector3d(0.07, 0.07, 0.07);  ///< Box: edge lengths along its x, y, z, metres
  double height = 0.07;                       ///< Cylinder: length along its axis, metres
  cv::Vec3d colour = cv::Vec3d(20, 120, 255);  ///< BGR 0..255 of a fully lit surface point (default orange)
  bool checkered = false;                     ///< checker pattern (ball: longitude/latitude) instead of plain colour
  cv::Vec3d colour2 = cv::Vec3d(255, 255, 255);  ///< BGR of the other checker squares, or of the texture blotches
  bool textured = false;                      ///< texture pattern: smooth random blotches of colour2 on the colour
  uint64_t texture_seed = 1;                  ///< layout of the texture blotches (same seed, same pattern)
  /// Box: BGR of the faces +x, -x, +y, -y, +z, -z of its own frame (empty: all `colour`); the -z face
  /// looks at the camera when unturned, the +x one after a quarter turn about the default axis
  std::vector<cv::Vec3d> face_colours;
  int checker_longitude = 8;                  ///< checker squares around the equator (even keeps the seam clean);
                                              ///< square: checker squares along x; box: along each face's
                                              ///< horizontal edge; cylinder: around its axis
  int checker_latitude = 4;                   ///< checker squares from pole to pole; square: along y (1: stripes);
                                              ///< box: along each face's other edge; cylinder: along its axis
  double spin = 0.0;                          ///< turn rate about `spin_axis`, rad/s (a ball's pattern, box, cylinder)
  Eigen::Vector3d spin_axis = Eigen::Vector3d::UnitY();  ///< axis of `spin` and `yaw` (need not be unit; not zero)
  double yaw = 0.0;                           ///< turn about `spin_axis` at t = 0, radians
  bool draw_string = false;                   ///< draw a thin dark string to the pivot (pendulum only)
  Trajectory trajectory;                      ///< motion of the centre and presence window

  /// Orientation at time t: the rotation (object frame -> camera frame) by yaw + spin * t about spin_axis.
  Eigen::Matrix3d orientation(double t) const;
};

/// A flat rectangle facing the camera (normal along -z), centred on its trajectory.
struct SceneOccluder
{
  std::string name;                            ///< label (for messages)
  double width = 0.3;                          ///< size along x, metres
  double height = 0.3;                         ///< size along y, metres
  cv::Vec3d colour = cv::Vec3d(150, 130, 110);  ///< BGR 0..255 (default greyish blue)
  Trajectory trajectory;                       ///< motion of the centre and presence window
};

/// The static backdrop: a plane facing the camera at `depth`, filling the whole view.
struct SceneBackground
{
  /// Appearance of the plane.
  enum class Type
  {
    Plain,     ///< uniform `colour`
    Cluttered  ///< procedural texture: smooth colour noise, rectangles, blobs, lines and target-coloured patches
  };

  Type type = Type::Plain;                      ///< appearance
  cv::Vec3d colour = cv::Vec3d(215, 220, 225);  ///< BGR: plain colour, or the mean tone of the clutter
  double depth = 2.5;                           ///< distance of the plane, metres (gives it its disparity)
  int rectangles = 90;                          ///< Cluttered: random rectangles (some rotated, some outlined)
  int blobs = 50;                               ///< Cluttered: random filled ellipses
  int lines = 25;                               ///< Cluttered: random thick lines
  int target_patches = 6;                       ///< Cluttered: patches in shades of the target's colour
  double fine_noise = 12.0;                     ///< Cluttered: amplitude of the fine grain texture, grey levels
  uint64_t seed = 1;                            ///< Cluttered: layout seed (independent of the sensor noise seed)
};

/// Directional light and ambient term of the Lambertian shading.
struct SceneLight
{
  /// Direction towards the light (need not be unit); default: from the upper left, on the camera side.
  Eigen::Vector3d direction = Eigen::Vector3d(-0.5, -0.7, -0.5);
  double ambient = 0.35;  ///< brightness of unlit surface, fraction of the lit colour, [0, 1]
};

/// Everything needed to render a sequence.
struct SceneDescription
{
  std::string name;                      ///< scene name (default: file name without extension)
  std::string source;                    ///< file it came from (empty when built in code)
  SceneCamera camera;                    ///< stereo camera
  SceneLight light;                      ///< shading
  SceneBackground background;            ///< backdrop
  std::vector<SceneSphere> objects;      ///< balls, squares, boxes, cylinders; objects[0] is the target (at least one)
  std::vector<SceneOccluder> occluders;  ///< rectangles in front of the balls
  double fps = 30.0;                     ///< frame rate, Hz
  int frames = 300;                      ///< number of stereo frames
  double noise_sigma = 2.0;              ///< Gaussian sensor noise, grey levels, independent per pixel/channel/image
  double noise_shot = 0.0;               ///< shot noise, [0, 10]: variance noise_sigma^2 + noise_shot * I (grey levels)
  SceneSensor sensor;                    ///< exposure, vignetting, gains, JPEG, published encoding (scene_sensor.h)
  uint64_t seed = 0;                     ///< sensor noise seed
  int target_roi_frame = 0;              ///< frame whose target bounding box teaches the tracker the target
  /// The target counts as visible when at least this fraction of its disc shows in both images.
  double min_visible_fraction = 0.5;

  /// The calibration of the pair.
  StereoGeometry geometry() const;
  /// Empty when renderable, otherwise every problem found, one per line, naming the field.
  std::string validate() const;
};

/// Read a scene from YAML (OpenCV FileStorage dialect; a missing "%YAML:1.0" first line is supplied).
/// Colours in the file are RGB 0..255 and are converted to BGR. Unknown or duplicated keys are errors
/// (they are almost always typos). Throws SceneError naming the file and the field on any problem.
SceneDescription loadScene(const std::string& path);

/// Renders frames of a scene by casting one ray per pixel of each camera, and reports ground truth.
/// The static backdrop is rendered once per camera at construction; each frame then costs the
/// occluders' and balls' projected boxes plus the sensor noise. Frame k does not depend on which
/// frames were rendered before (noise is seeded per frame and view). Not thread-safe (scratch buffers).
class SceneRenderer
{
public:
  /// Throws SceneError when scene.validate() reports problems.
  explicit SceneRenderer(const SceneDescription& scene);

  /// The scene being rendered.
  const SceneDescription& scene() const { return scene_; }
  /// Number of frames.
  int frames() const { return scene_.frames; }
  /// Time of frame k, seconds since frame 0 (k / fps).
  double stamp(int k) const { return k / scene_.fps; }
  /// Calibration of the rectified pair.
  StereoGeometry geometry() const { return scene_.geometry(); }

  /// Render frame k into CV_8UC3 BGR images (reallocated only when needed), through the scene's sensor
  /// (motion blur, vignetting, gains, noise, JPEG: SceneSensorModel). The per-pixel noise is added unless
  /// `with_noise` is false (useful for checking colours exactly); the other sensor effects always apply.
  void render(int k, cv::Mat& left_bgr, cv::Mat& right_bgr, bool with_noise = true);
  /// Render frame k as render() does and return it as the tracker's input: those images (shared: keep them
  /// alive while the frame is used), stamped stamp(k), with the pair's geometry().
  StereoFrame renderFrame(int k, cv::Mat& left_bgr, cv::Mat& right_bgr, bool with_noise = true);
  /// Render one view of frame k.
  void renderView(int k, View view, cv::Mat& bgr, bool with_noise = true);
  /// Renders averaged over frame k's exposure: sensor.blur_samples, or when that is 0 enough that no
  /// object moves more than about a pixel between two of them (at most 16); 1 without exposure.
  int blurSamples(int k) const;
  /// The sensor model applied after rendering (gains, vignetting factors).
  const SceneSensorModel& sensorModel() const { return sensor_; }

  /// Centre of object i at frame k, left optical frame, metres.
  Eigen::Vector3d objectPosition(size_t i, int k) const;
  /// True when object i exists at frame k.
  bool objectPresent(size_t i, int k) const;
  /// Fraction [0, 1] of object i's projected silhouette (any shape) in `view` that is inside the
  /// image and not hidden by a nearer object or occluder (0 when absent or behind the camera).
  double visibleFraction(size_t i, int k, View view) const;
  /// Bounding box of object i's projection in `view` (pixels whose centres fall inside the silhouette's
  /// extent), clipped to the image; empty when absent, behind the camera or out of view. Occlusion is
  /// ignored: the box says where the object is, visibleFraction() how much of it shows.
  cv::Rect objectRoi(size_t i, int k, View view) const;

  /// Ground-truth centre of the target (objects[0]) at frame k, left optical frame, metres.
  Eigen::Vector3d targetPosition(int k) const { return objectPosition(0, k); }
  /// True when the target is present and at least min_visible_fraction of it shows in both images.
  bool targetVisible(int k) const;
  /// Bounding box of the target in the left image (see objectRoi()).
  cv::Rect targetRoi(int k) const { return objectRoi(0, k, View::Left); }

private:
  /// The light reaching `view` at time t (no sensor effects): backdrop, occluders, objects, strings.
  void drawScene(double t, View view, cv::Mat& bgr);
  /// The camera whose rays render `view`: the ideal one, with the right camera's principal point moved
  /// down by camera.row_offset (ground truth and geometry() keep the ideal camera).
  const SceneCamera& imagingCamera(View view) const { return imaging_[static_cast<int>(view)]; }
  /// Paint the background plane once and resample it into each camera (backdrop_, backdrop_depth_).
  void renderBackdrop();
  /// Draw the occluders present at time t, depth-tested against and writing into `depth`.
  void drawOccluders(double t, View view, cv::Mat& img, cv::Mat& depth) const;
  /// Ray-cast one ball inside its projected bounding box, shaded, with an anti-aliased rim.
  void drawSphere(const SceneSphere& s, double t, View view, cv::Mat& img, cv::Mat& depth) const;
  /// Draw one flat square object (constant shading, pattern, area-coverage anti-aliased edges).
  void drawSquare(const SceneSphere& s, double t, View view, cv::Mat& img, cv::Mat& depth) const;
  /// Ray-cast one box or cylinder (per-face Lambertian shading, patterns, supersampled edges; scene_shapes.cpp).
  void drawSolid(const SceneSphere& s, double t, View view, cv::Mat& img, cv::Mat& depth) const;
  /// Draw a pendulum ball's string as depth-tested samples of the 3D segment pivot-centre.
  void drawString(const SceneSphere& s, double t, View view, cv::Mat& img, const cv::Mat& depth) const;
  /// Ray parameter of the nearest surface other than object i (other balls, occluders, background).
  double nearestOtherHit(size_t i, double t, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir) const;
  /// Optical centre of a camera in the left optical frame.
  Eigen::Vector3d cameraOrigin(View view) const;

  SceneDescription scene_;
  Eigen::Vector3d light_;           ///< unit vector towards the light
  cv::Mat backdrop_[2];             ///< static background per view, CV_8UC3
  cv::Mat backdrop_depth_[2];       ///< its depth per view, CV_32F
  cv::Mat depth_;                   ///< per-frame depth scratch buffer, CV_32F
  SceneCamera imaging_[2];          ///< per view: the camera its rays are cast from (see imagingCamera())
  SceneSensorModel sensor_;         ///< everything after the light reaches the sensor
  cv::Mat sub_frame_;               ///< one render of a motion-blurred exposure, CV_8UC3
  cv::Mat exposure_sum_;            ///< their mean, CV_32FC3
};

}  // namespace stereo_pf
