// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// HSI colour space (thesis ch. 4.1) and its quantisation into histogram bins.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "stereo_pf/core/feature_cache.h"
#include "stereo_pf/core/parameters.h"

namespace stereo_pf
{
/// One HSI triple: hue in degrees [0, 360), saturation and intensity in [0, 1].
struct Hsi
{
  double h = 0.0;  ///< hue angle, degrees in [0, 360): 0 red, 120 green, 240 blue; 0 for greys
  double s = 0.0;  ///< saturation in [0, 1]: 0 for greys (and black)
  double i = 0.0;  ///< intensity in [0, 1]
};

/// Convert one RGB colour (0..255 each) to HSI: I = (R+G+B)/(3*255), S = 1 - min(R,G,B)/mean(R,G,B),
/// H = atan2(sqrt(3)(G-B), 2R-G-B) in degrees (0 = red, 120 = green, 240 = blue); H = 0 and S = 0 for
/// greys, S = 0 for black.
Hsi rgbToHsi(double r, double g, double b);

/// Settings of the HSI histogram: hue_bins x saturation_bins x intensity_bins bins, index
/// (hue_bin * saturation_bins + saturation_bin) * intensity_bins + intensity_bin.
struct HsiBinning
{
  /// Number of hue bins (equal slices of [0, 360), bin 0 starts at red).
  int hue_bins = 8;
  /// Number of saturation bins (equal slices of [0, 1]).
  int saturation_bins = 8;
  /// Number of intensity bins (equal slices of [0, 1]).
  int intensity_bins = 4;
  /// Pixels with saturation below this are achromatic: their hue is meaningless, so they all go
  /// to hue bin 0 and are told apart by saturation and intensity (this is what makes white/grey
  /// targets trackable).
  double achromatic_saturation = 0.1;
  /// Pixels darker than this (intensity) are also treated as achromatic (hue of near-black is noise).
  double achromatic_intensity = 0.08;
  /// More than intensity_bins: achromatic pixels are told apart by intensity alone, in this many equal slices
  /// of [0, 1], laid over the bins no chromatic pixel then uses (saturation bin 0 of every hue); at most
  /// hue_bins x intensity_bins. A grey image has nothing else: 4 intensity bins put a faint grey ball and the
  /// dark wall behind it in one bin. Up to intensity_bins: the binning above (saturation and intensity bins).
  /// Target files from before it was stored read as intensity_bins.
  int grey_levels = 4;

  /// Largest number of bins: bin images are CV_8UC1.
  static constexpr int kMaxBins = 256;

  /// Total number of bins.
  int bins() const { return hue_bins * saturation_bins * intensity_bins; }
  /// Bin index of an HSI triple, in [0, bins()).
  int bin(const Hsi& hsi) const;
  /// Throws std::invalid_argument when a bin count is < 1, bins() > kMaxBins, or a threshold is
  /// outside [0, 1].
  void validate() const;
  /// Compact text naming every setting, e.g. "8x8x4/s0.100000/i0.080000/g4" (cache keys, messages).
  std::string describe() const;
  /// True when both binnings produce the same bin for every colour.
  bool sameAs(const HsiBinning& other) const;

  /// Read hue_bins (8, 1..64), saturation_bins (8, 1..64), intensity_bins (4, 1..64), achromatic_saturation
  /// (0.1, 0..1), achromatic_intensity (0.08, 0..1) and grey_levels (intensity_bins, 1..hue_bins x intensity_bins) from
  /// `params`; throws ParameterError naming the parameter, or all three bin counts when their product exceeds
  /// kMaxBins.
  static HsiBinning fromParameters(const Parameters& params);
  /// True when bin `b` holds colours, whose intensity a change of shading moves (a face turning away from the
  /// light darkens, its hue and saturation stay): every bin but the grey ones (saturation bin 0, of hue bin 0
  /// only unless grey_levels > intensity_bins).
  bool isChromaticBin(int b) const;
  /// `q` (one value per bin) with each chromatic bin's mass also given, times `tolerance`, to the bins one
  /// intensity slice darker and lighter of the same hue and saturation (grey bins, which intensity alone tells
  /// apart, keep theirs), normalised to sum 1. A comparison with it forgives a change of shading by one
  /// intensity slice. `q` as given when nothing is spread (tolerance 0, or no colour bin holds mass). Throws
  /// std::invalid_argument when `q` has not bins() entries.
  std::vector<double> spreadAlongIntensity(const std::vector<double>& q, double tolerance) const;
  /// Write the six settings into the open map of `fs` (target files).
  void write(cv::FileStorage& fs) const;
  /// Read them back from a map written by write(); false with `error` naming the missing key.
  static bool read(const cv::FileNode& node, HsiBinning& binning, std::string& error);
  /// Read the binning stored in a target map and check that it is this one; false with `error` saying which
  /// key is missing, or both binnings (a target learned with another binning means nothing here).
  bool matches(const cv::FileNode& node, std::string& error) const;
};

/// Maps BGR pixels to HSI bin indices through a lookup table on 6-bit-per-channel colour
/// (building it costs 2^18 conversions once, a few ms; each pixel then costs one table read).
class HsiBinner
{
public:
  /// Validates `binning` (std::invalid_argument when invalid) and builds the table.
  explicit HsiBinner(const HsiBinning& binning = HsiBinning());
  /// The settings the table was built with.
  const HsiBinning& binning() const { return binning_; }
  /// Bin of one BGR pixel.
  uint8_t bin(uint8_t b, uint8_t g, uint8_t r) const { return lut_[((b >> 2) << 12) | ((g >> 2) << 6) | (r >> 2)]; }
  /// Bin of one grey pixel (R = G = B = v), at full 8-bit resolution.
  uint8_t binGray(uint8_t v) const { return gray_lut_[v]; }
  /// Fill `bins` (CV_8UC1, same size; its buffer is reused when it already fits) with the bin index of
  /// every pixel of a CV_8UC3 BGR, CV_8UC4 BGRA or CV_8UC1 grey image. Throws std::invalid_argument for
  /// other types. With `gain` != 1 (applied in steps of 1/64) each channel value v is first scaled by it (and
  /// clipped at 255).
  void binImage(const cv::Mat& image, cv::Mat& bins, double gain = 1.0) const;
  /// `out` (CV_8UC1, image.cols / cell x image.rows / cell) holds, per `cell` x `cell` block of `image` (as
  /// binImage() takes it, at `gain`), the mean of `weight[bin]` over its pixels, rounded: what binning the image,
  /// looking each bin up in `weight` and shrinking by area to the blocks gives, in one pass and without the bin
  /// image. The last image.cols % cell columns and image.rows % cell rows are in no block. `cell`: 1 to 16
  /// (std::invalid_argument otherwise, and for the types binImage() refuses).
  void cellMeans(const cv::Mat& image, const std::array<uint8_t, 256>& weight, int cell, cv::Mat& out,
                 double gain = 1.0) const;

  /// Bins of single pixels of one image at one gain, exactly as binImage() gives them: for a few hypotheses
  /// spread over the image (the background places beside the best particle span whole rows), whose samples
  /// are far fewer than the pixels between them. Valid while the binner and the image live.
  class PixelBins
  {
  public:
    /// Bin of pixel (x, y), which must lie in the image (not checked).
    uint8_t at(int x, int y) const
    {
      const uint8_t* p = image_->ptr<uint8_t>(y) + static_cast<size_t>(x) * channels_;
      return channels_ == 1 ? grey_[p[0]] : colour_[((p[0] >> 2) << 12) | ((p[1] >> 2) << 6) | (p[2] >> 2)];
    }

  private:
    friend class HsiBinner;
    const cv::Mat* image_ = nullptr;
    int channels_ = 1;
    const uint8_t* colour_ = nullptr;
    std::array<uint8_t, 256> grey_{};
  };
  /// The pixel bins of `image` (as binImage() takes it) at `gain`.
  PixelBins pixelBins(const cv::Mat& image, double gain = 1.0) const;

  /// The bin-index image of `view` of the cache's frame, through the cache under the key
  /// "hsi_bins/<binning>" (so every model with the same binning shares it), at the cache's gain for that view
  /// (FeatureCache::gain()); only rows [y0, y1) are guaranteed (FeatureCache::getRows()).
  const cv::Mat& cachedBins(FeatureCache& cache, View view, int y0, int y1) const;
  /// The same, of which only the pixels of `region` are guaranteed (FeatureCache::getRegion()).
  const cv::Mat& cachedBins(FeatureCache& cache, View view, const cv::Rect& region) const;

private:
  /// Gains are applied in steps of 1/kGainSteps.
  static constexpr int kGainSteps = 64;
  /// Tables kept for gains other than 1 (256 KB each); more distinct gains start the collection afresh.
  static constexpr size_t kMaxGainTables = 16;
  /// The table for gain step / kGainSteps: built on first use from the table at gain 1, then kept.
  const uint8_t* gainTable(int step) const;
  /// The tables binImage() reads for an image of OpenCV type `type` at `gain`: the colour table (gain 1's or
  /// gainTable()'s) and the grey levels' (scaled by the gain for grey images). Throws std::invalid_argument for
  /// a type other than CV_8UC1, CV_8UC3 and CV_8UC4, naming it.
  void tables(int type, double gain, const uint8_t*& colour, std::array<uint8_t, 256>& grey) const;

  HsiBinning binning_;
  std::string cache_key_;
  std::vector<uint8_t> lut_;
  mutable std::map<int, std::vector<uint8_t>> gain_luts_;
  std::array<uint8_t, 256> gray_lut_{};
};

}  // namespace stereo_pf
