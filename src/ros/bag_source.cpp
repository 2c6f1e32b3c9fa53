// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/ros/bag_source.h"

#include <set>
#include <stdexcept>

#include <geometry_msgs/PointStamped.h>
#include <sensor_msgs/RegionOfInterest.h>
#include <std_msgs/Bool.h>

namespace stereo_pf
{
namespace
{
std::string strip(const std::string& topic)
{
  return !topic.empty() && topic[0] == '/' ? topic.substr(1) : topic;
}
}  // namespace

BagSource::BagSource(const std::string& path, const BagTopics& topics, bool assume_rectified)
  : topics_(topics), assume_rectified_(assume_rectified)
{
  try
  {
    bag_.open(path, rosbag::bagmode::Read);
  }
  catch (const rosbag::BagException& e)
  {
    throw std::runtime_error("cannot open bag '" + path + "': " + e.what());
  }
  // Which topics does the bag have? Compare without leading slashes.
  std::set<std::string> present;
  std::string listing;
  {
    rosbag::View all(bag_);
    for (const rosbag::ConnectionInfo* c : all.getConnections())
      if (present.insert(strip(c->topic)).second)
        listing += "\n  " + c->topic + " [" + c->datatype + "]";
  }
  for (const std::string& t : { topics_.left_image, topics_.right_image, topics_.left_info, topics_.right_info })
    if (!present.count(strip(t)))
      throw std::runtime_error("bag '" + path + "' has no topic '" + t + "'; it has:" + listing);

  // Ground truth is small: read it all first, indexed by stamp.
  auto with_slash = [](const std::string& t) { return std::vector<std::string>{ strip(t), "/" + strip(t) }; };
  for (const rosbag::MessageInstance& m : rosbag::View(bag_, rosbag::TopicQuery(with_slash(topics_.truth))))
    if (auto p = m.instantiate<geometry_msgs::PointStamped>())
      truth_[p->header.stamp.toNSec()] = Eigen::Vector3d(p->point.x, p->point.y, p->point.z);
  for (const rosbag::MessageInstance& m : rosbag::View(bag_, rosbag::TopicQuery(with_slash(topics_.truth_roi))))
    if (auto r = m.instantiate<sensor_msgs::RegionOfInterest>())
      roi_[m.getTime().toNSec()] = cv::Rect(r->x_offset, r->y_offset, r->width, r->height);
  for (const rosbag::MessageInstance& m : rosbag::View(bag_, rosbag::TopicQuery(with_slash(topics_.truth_visible))))
    if (auto b = m.instantiate<std_msgs::Bool>())
      visible_[m.getTime().toNSec()] = b->data;

  std::vector<std::string> wanted;
  for (const std::string& t : { topics_.left_image, topics_.right_image, topics_.left_info, topics_.right_info })
    for (const std::string& s : with_slash(t))
      wanted.push_back(s);
  view_ = std::make_unique<rosbag::View>(bag_, rosbag::TopicQuery(wanted));
  it_ = view_->begin();
}

BagSource::~BagSource()
{
  view_.reset();
  bag_.close();
}

void BagSource::drop(const std::string& reason, int count)
{
  dropped_ += count;
  drop_reasons_[reason] += count;
}

bool BagSource::assemble(uint64_t stamp, BagFrame& out)
{
  sensor_msgs::ImageConstPtr l = left_[stamp], r = right_[stamp];
  // Anything older than this pair can no longer be matched (ExactTime): drop it.
  for (auto* buffer : { &left_, &right_ })
  {
    auto end = buffer->upper_bound(stamp);
    for (auto k = buffer->begin(); k != end; ++k)
      if (k->first != stamp)
        drop("image without a partner of the same stamp (unsynchronised pair)");
    buffer->erase(buffer->begin(), end);
  }
  std::string error;
  if (!calibration_.update(*left_info_, *right_info_, error))
    return drop("invalid camera_info: " + error), false;
  cv::Mat left, right;
  if (!toEngineImage(l, left, out.keep_left, error) || !toEngineImage(r, right, out.keep_right, error))
    return drop(error), false;
  if (left.size() != right.size() || left.type() != right.type())
    return drop("left and right images differ in size or encoding"), false;
  StereoFrame& f = out.frame;
  f.geometry = calibration_.geometry();
  f.stamp = l->header.stamp.toSec();
  if (assume_rectified_)
  {
    f.left = left;
    f.right = right;
  }
  else
  {
    calibration_.rectify(View::Left, left, f.left);
    calibration_.rectify(View::Right, right, f.right);
  }
  const std::string invalid = f.validate();
  if (!invalid.empty())
    return drop(invalid), false;

  out.index = delivered_++;
  const auto t = truth_.find(stamp);
  out.has_truth = t != truth_.end();
  if (out.has_truth)
    out.truth = t->second;
  const auto roi = roi_.find(stamp);
  out.has_roi = roi != roi_.end();
  if (out.has_roi)
    out.roi = roi->second;
  const auto vis = visible_.find(stamp);
  out.has_visible = vis != visible_.end();
  out.visible = out.has_visible ? vis->second : true;
  return true;
}

bool BagSource::next(BagFrame& out)
{
  const std::string li = strip(topics_.left_info), ri = strip(topics_.right_info), lt = strip(topics_.left_image);
  for (; it_ != view_->end();)
  {
    {
      // Take what we need from the message before advancing: the iterator owns the instance.
      const rosbag::MessageInstance& m = *it_;
      const std::string topic = strip(m.getTopic());
      if (topic == li || topic == ri)
        (topic == li ? left_info_ : right_info_) = m.instantiate<sensor_msgs::CameraInfo>();
      else if (auto image = m.instantiate<sensor_msgs::Image>())
        (topic == lt ? left_ : right_)[image->header.stamp.toNSec()] = image;
    }
    ++it_;
    // A complete pair waits for both camera_infos (they may come just after their images).
    if (!left_info_ || !right_info_)
      continue;
    for (const auto& kv : left_)
      if (right_.count(kv.first))
      {
        if (assemble(kv.first, out))
          return true;
        break;
      }
  }
  const int leftover = static_cast<int>(left_.size() + right_.size());
  if (leftover > 0)
    drop(left_info_ && right_info_ ? "image without a partner of the same stamp (unsynchronised pair)" :
                                     "no camera_info in the bag",
         leftover);
  left_.clear();
  right_.clear();
  return false;
}

}  // namespace stereo_pf
