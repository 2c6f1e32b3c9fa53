// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/core/colour.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include <opencv2/core/hal/intrin.hpp>

#include "stereo_pf/core/area_means.h"

namespace stereo_pf
{
namespace
{
constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

// floor(x * n) clamped into [0, n-1]: x == 1 (full saturation / white) belongs to the top bin.
inline int sliceOf(double x, int n)
{
  const int k = static_cast<int>(x * n);
  return k < 0 ? 0 : (k >= n ? n - 1 : k);
}

/// One row of `cols` pixels of `channels` (1, 3 or 4) channels at `p` to `o`: each pixel's bin (`lut` for colour,
/// `grey` for grey levels), or with `Weighted` that bin's entry of `weight`.
template <bool Weighted>
void binRow(const uint8_t* p, int cols, int channels, const uint8_t* lut, const uint8_t* grey, const uint8_t* weight,
            uint8_t* o)
{
  auto put = [weight](uint8_t bin) { return Weighted ? weight[bin] : bin; };
  int x = 0;
  if (channels == 1)
  {
    for (; x < cols; ++x)
      o[x] = put(grey[p[x]]);
    return;
  }
  if (channels == 4)
  {
    for (; x < cols; ++x, p += 4)
      o[x] = put(lut[((p[0] >> 2) << 12) | ((p[1] >> 2) << 6) | (p[2] >> 2)]);
    return;
  }
#if CV_SIMD128
  // The loop is bound by instruction count, not by the table reads, so build 16 pixels' indices at once:
  // (b >> 2) << 12 | (g >> 2) << 6 | r >> 2 as hi = (b & 0xFC) << 4 | g >> 2 (12 bits, 16-bit lanes), and
  // lo = (r & 0xFC) << 8; interleaving lo and hi gives the 32-bit lo | hi << 16, and >> 10 the index.
  // The table reads stay scalar (SSE2 has no gather).
  {
    const cv::v_uint16x8 mask_b = cv::v_setall_u16(0xFC);
    const cv::v_uint16x8 mask_r = cv::v_setall_u16(0xFC00);
    alignas(16) uint32_t idx[16];
    for (; x + 16 <= cols; x += 16, p += 48)
    {
      cv::v_uint8x16 b, g, r;
      cv::v_load_deinterleave(p, b, g, r);
      cv::v_uint16x8 b16[2], g16[2], r16[2];
      cv::v_expand(b, b16[0], b16[1]);
      cv::v_expand(g, g16[0], g16[1]);
      cv::v_uint8x16 r_lo, r_hi;
      cv::v_zip(cv::v_setzero_u8(), r, r_lo, r_hi);  // r << 8 in 16-bit lanes
      r16[0] = cv::v_reinterpret_as_u16(r_lo);
      r16[1] = cv::v_reinterpret_as_u16(r_hi);
      for (int h = 0; h < 2; ++h)
      {
        const cv::v_uint16x8 hi = cv::v_shl<4>(b16[h] & mask_b) | cv::v_shr<2>(g16[h]);
        cv::v_uint16x8 w0, w1;
        cv::v_zip(r16[h] & mask_r, hi, w0, w1);
        cv::v_store_aligned(idx + 8 * h, cv::v_shr<10>(cv::v_reinterpret_as_u32(w0)));
        cv::v_store_aligned(idx + 8 * h + 4, cv::v_shr<10>(cv::v_reinterpret_as_u32(w1)));
      }
#pragma GCC unroll 16
      for (int k = 0; k < 16; ++k)
        o[x + k] = put(lut[idx[k]]);
    }
  }
#elif defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
  // The loop is bound by instruction count, not by the table read (measured: an all-black image is
  // barely faster), so read 4 pixels with two 8-byte loads and build each index with 3 shifts/masks
  // from a little-endian word b | g << 8 | r << 16. ~25% faster than byte-wise reads.
  // The second load reads 2 bytes past the 4th pixel, so stop while one more pixel of this row follows.
  auto index = [](uint32_t w) { return ((w & 0xFCu) << 10) | ((w >> 4) & 0xFC0u) | ((w >> 18) & 0x3Fu); };
  for (; x + 4 < cols; x += 4, p += 12)
  {
    uint64_t a = 0;
    uint64_t b = 0;
    std::memcpy(&a, p, 8);
    std::memcpy(&b, p + 6, 8);
    o[x] = put(lut[index(static_cast<uint32_t>(a))]);
    o[x + 1] = put(lut[index(static_cast<uint32_t>(a >> 24))]);
    o[x + 2] = put(lut[index(static_cast<uint32_t>(b))]);
    o[x + 3] = put(lut[index(static_cast<uint32_t>(b >> 24))]);
  }
#endif
  for (; x < cols; ++x, p += 3)
    o[x] = put(lut[((p[0] >> 2) << 12) | ((p[1] >> 2) << 6) | (p[2] >> 2)]);
}
}  // namespace

Hsi rgbToHsi(double r, double g, double b)
{
  Hsi out;
  const double sum = r + g + b;
  out.i = sum / (3.0 * 255.0);
  if (sum <= 0.0)
    return out;  // black: no hue, no saturation
  const double mn = std::min(r, std::min(g, b));
  const double mx = std::max(r, std::max(g, b));
  out.s = 1.0 - 3.0 * mn / sum;
  if (mx - mn <= 0.0)
  {
    out.s = 0.0;  // exact grey: atan2(0, 0) would be an arbitrary angle
    return out;
  }
  // The standard HSI hue (Gonzalez & Woods) in its atan2 form: no acos domain problems near greys.
  double h = std::atan2(std::sqrt(3.0) * (g - b), 2.0 * r - g - b) * kRadToDeg;
  if (h < 0.0)
    h += 360.0;
  if (h >= 360.0)
    h -= 360.0;
  out.h = h;
  return out;
}

int HsiBinning::bin(const Hsi& hsi) const
{
  const bool achromatic = hsi.s < achromatic_saturation || hsi.i < achromatic_intensity;
  if (achromatic && grey_levels > intensity_bins)
  {
    // Grey levels: the (hue, saturation 0, intensity) bins taken in order, finer in intensity than colours are.
    const int level = sliceOf(hsi.i, std::clamp(grey_levels, 1, hue_bins * intensity_bins));
    return ((level / intensity_bins) * saturation_bins) * intensity_bins + level % intensity_bins;
  }
  // Achromatic colours share hue bin 0; saturation and intensity still separate white, grey and black. With
  // grey levels, saturation bin 0 holds them: a colour just above the achromatic threshold goes to bin 1.
  const int hb = achromatic ? 0 : sliceOf(hsi.h / 360.0, hue_bins);
  const int sb = std::max(grey_levels > intensity_bins && saturation_bins > 1 ? 1 : 0, sliceOf(hsi.s, saturation_bins));
  const int ib = sliceOf(hsi.i, intensity_bins);
  return (hb * saturation_bins + sb) * intensity_bins + ib;
}

bool HsiBinning::isChromaticBin(int b) const
{
  const int sb = (b / intensity_bins) % saturation_bins;
  const int hb = b / (intensity_bins * saturation_bins);
  return sb > 0 || (hb > 0 && grey_levels <= intensity_bins);
}

std::vector<double> HsiBinning::spreadAlongIntensity(const std::vector<double>& q, double tolerance) const
{
  if (static_cast<int>(q.size()) != bins())
    throw std::invalid_argument("HsiBinning::spreadAlongIntensity: " + std::to_string(q.size()) +
                                " values for " + std::to_string(bins()) + " bins");
  std::vector<double> out(q);
  bool spread = false;
  if (tolerance > 0.0)
    for (int b = 0; b < bins(); ++b)
    {
      if (!isChromaticBin(b) || !(q[static_cast<size_t>(b)] > 0.0))
        continue;
      spread = true;
      const int ib = b % intensity_bins;
      if (ib > 0)
        out[static_cast<size_t>(b - 1)] += tolerance * q[static_cast<size_t>(b)];
      if (ib + 1 < intensity_bins)
        out[static_cast<size_t>(b + 1)] += tolerance * q[static_cast<size_t>(b)];
    }
  if (!spread)
    return out;  // as given, to the last bit
  double sum = 0.0;
  for (double v : out)
    sum += v;
  if (sum > 0.0)
    for (double& v : out)
      v /= sum;
  return out;
}

void HsiBinning::validate() const
{
  if (hue_bins < 1 || saturation_bins < 1 || intensity_bins < 1)
    throw std::invalid_argument("HSI binning " + describe() + ": every bin count must be at least 1");
  // Compare in 64 bits: three large ints could overflow the product.
  const long long total = static_cast<long long>(hue_bins) * saturation_bins * intensity_bins;
  if (total > kMaxBins)
    throw std::invalid_argument("HSI binning " + describe() + " has " + std::to_string(total) +
                                " bins; at most " + std::to_string(kMaxBins) + " fit a CV_8UC1 bin image");
  if (!(achromatic_saturation >= 0.0 && achromatic_saturation <= 1.0) ||
      !(achromatic_intensity >= 0.0 && achromatic_intensity <= 1.0))
    throw std::invalid_argument("HSI binning " + describe() + ": achromatic thresholds must lie in [0, 1]");
  if (grey_levels < 1 || grey_levels > hue_bins * intensity_bins)
    throw std::invalid_argument("HSI binning " + describe() + ": grey_levels must lie in [1, hue_bins x intensity_bins]");
}

std::string HsiBinning::describe() const
{
  char buf[128];
  std::snprintf(buf, sizeof(buf), "%dx%dx%d/s%.6f/i%.6f/g%d", hue_bins, saturation_bins, intensity_bins,
                achromatic_saturation, achromatic_intensity, grey_levels);
  return buf;
}

HsiBinning HsiBinning::fromParameters(const Parameters& p)
{
  HsiBinning b;
  b.hue_bins = p.getInt("hue_bins", 8, 1, 64,
                        "hue bins of the HSI histogram (the three counts' product at most the plugin's maximum)");
  b.saturation_bins = p.getInt("saturation_bins", 8, 1, 64, "saturation bins of the HSI histogram");
  b.intensity_bins = p.getInt("intensity_bins", 4, 1, 64, "intensity bins of the HSI histogram");
  b.achromatic_saturation = p.getDouble("achromatic_saturation", 0.1, 0.0, 1.0,
                                        "pixels below this saturation go to the achromatic (grey) bins");
  b.achromatic_intensity = p.getDouble("achromatic_intensity", 0.08, 0.0, 1.0,
                                       "pixels below this intensity go to the achromatic (grey) bins");
  b.grey_levels = p.getInt("grey_levels", b.intensity_bins, 1, b.hue_bins * b.intensity_bins,
                           "intensity slices of the achromatic pixels (at most hue_bins x intensity_bins)");
  if (b.bins() > kMaxBins)
  {
    const std::string ns = p.prefix().empty() ? "" : p.prefix() + "/";
    throw ParameterError("parameters '" + ns + "hue_bins' x '" + ns + "saturation_bins' x '" + ns +
                         "intensity_bins' = " + std::to_string(b.hue_bins) + " x " + std::to_string(b.saturation_bins) +
                         " x " + std::to_string(b.intensity_bins) + " = " + std::to_string(b.bins()) +
                         " bins; at most " + std::to_string(kMaxBins) + " are allowed");
  }
  return b;
}

void HsiBinning::write(cv::FileStorage& fs) const
{
  fs << "hue_bins" << hue_bins << "saturation_bins" << saturation_bins << "intensity_bins" << intensity_bins;
  fs << "achromatic_saturation" << achromatic_saturation << "achromatic_intensity" << achromatic_intensity;
  fs << "grey_levels" << grey_levels;
}

bool HsiBinning::read(const cv::FileNode& m, HsiBinning& b, std::string& error)
{
  for (const char* key : { "hue_bins", "saturation_bins", "intensity_bins", "achromatic_saturation",
                           "achromatic_intensity" })
    if (!m[key].isInt() && !m[key].isReal())
    {
      error = std::string("lacks the number '") + key + "'";
      return false;
    }
  b.hue_bins = static_cast<int>(m["hue_bins"]);
  b.saturation_bins = static_cast<int>(m["saturation_bins"]);
  b.intensity_bins = static_cast<int>(m["intensity_bins"]);
  b.achromatic_saturation = static_cast<double>(m["achromatic_saturation"]);
  b.achromatic_intensity = static_cast<double>(m["achromatic_intensity"]);
  b.grey_levels = m["grey_levels"].isInt() ? static_cast<int>(m["grey_levels"]) : b.intensity_bins;
  return true;
}

bool HsiBinning::matches(const cv::FileNode& node, std::string& error) const
{
  HsiBinning stored;
  std::string reason;
  if (!read(node, stored, reason))
  {
    error = "the target " + reason;
    return false;
  }
  if (!stored.sameAs(*this))
  {
    error = "the target was learned with HSI binning " + stored.describe() +
            " (hue x saturation x intensity / achromatic thresholds) but this model is configured with " +
            describe() + "; relearn the target or set the same binning";
    return false;
  }
  return true;
}

bool HsiBinning::sameAs(const HsiBinning& other) const
{
  return hue_bins == other.hue_bins && saturation_bins == other.saturation_bins &&
         intensity_bins == other.intensity_bins &&
         std::abs(achromatic_saturation - other.achromatic_saturation) <= 1e-9 &&
         std::abs(achromatic_intensity - other.achromatic_intensity) <= 1e-9 && grey_levels == other.grey_levels;
}

HsiBinner::HsiBinner(const HsiBinning& binning)
  : binning_(binning), cache_key_("hsi_bins/" + binning.describe()), lut_(1u << 18)
{
  binning_.validate();
  // Each 6-bit cell is represented by its centre value, so the table does not bias towards darker colours.
  auto centre = [](int q) { return q * 4.0 + 1.5; };
  for (int qb = 0; qb < 64; ++qb)
    for (int qg = 0; qg < 64; ++qg)
      for (int qr = 0; qr < 64; ++qr)
        lut_[(qb << 12) | (qg << 6) | qr] =
            static_cast<uint8_t>(binning_.bin(rgbToHsi(centre(qr), centre(qg), centre(qb))));
  // Grey images have only 256 colours: bin them exactly instead of through the 6-bit table.
  for (int v = 0; v < 256; ++v)
    gray_lut_[v] = static_cast<uint8_t>(binning_.bin(rgbToHsi(v, v, v)));
}

const cv::Mat& HsiBinner::cachedBins(FeatureCache& cache, View view, int y0, int y1) const
{
  const int cols = cache.image(view).cols;
  return cachedBins(cache, view, cv::Rect(0, y0, cols, std::max(0, y1 - y0)));
}

const cv::Mat& HsiBinner::cachedBins(FeatureCache& cache, View view, const cv::Rect& region) const
{
  const double gain = cache.gain(view);
  return cache.getRegion(view, cache_key_, region, [this, gain](const cv::Mat& image, cv::Mat& out, const cv::Rect& r) {
    out.create(image.size(), CV_8UC1);
    if (r.empty())
      return;
    cv::Mat part = out(r);  // the right size and type: binImage() fills it in place
    binImage(image(r), part, gain);
  });
}

const uint8_t* HsiBinner::gainTable(int step) const
{
  auto found = gain_luts_.find(step);
  if (found != gain_luts_.end())
    return found->second.data();
  if (gain_luts_.size() >= kMaxGainTables)
    gain_luts_.clear();
  // The table at gain 1 read at each cell's scaled value: one pass of 2^18 reads, once per gain step,
  // then every pixel costs what it does at gain 1.
  std::array<uint32_t, 64> cell;
  for (int q = 0; q < 64; ++q)
    cell[q] = static_cast<uint32_t>(
        std::min(63.0, std::floor((q * 4.0 + 1.5) * static_cast<double>(step) / kGainSteps / 4.0)));
  std::vector<uint8_t>& table = gain_luts_[step];
  table.resize(lut_.size());
  for (uint32_t i = 0; i < table.size(); ++i)
    table[i] = lut_[(cell[i >> 12] << 12) | (cell[(i >> 6) & 63u] << 6) | cell[i & 63u]];
  return table.data();
}

void HsiBinner::tables(int type, double gain, const uint8_t*& colour, std::array<uint8_t, 256>& grey) const
{
  if (type != CV_8UC3 && type != CV_8UC1 && type != CV_8UC4)
    throw std::invalid_argument("HsiBinner: expected a CV_8UC3 (BGR), CV_8UC4 (BGRA) or CV_8UC1 image, got type " +
                                std::to_string(type));
  colour = lut_.data();
  grey = gray_lut_;
  const int step = std::isfinite(gain) ? static_cast<int>(std::lround(std::clamp(gain, 0.25, 4.0) * kGainSteps))
                                       : kGainSteps;
  if (step != kGainSteps && CV_MAT_CN(type) == 1)
    for (int v = 0; v < 256; ++v)
      grey[v] = gray_lut_[std::min(255L, std::lround(v * static_cast<double>(step) / kGainSteps))];
  else if (step != kGainSteps)
    colour = gainTable(step);
}

HsiBinner::PixelBins HsiBinner::pixelBins(const cv::Mat& image, double gain) const
{
  PixelBins out;
  tables(image.type(), gain, out.colour_, out.grey_);
  out.image_ = &image;
  out.channels_ = image.channels();
  return out;
}

void HsiBinner::binImage(const cv::Mat& image, cv::Mat& bins, double gain) const
{
  const uint8_t* lut = nullptr;
  std::array<uint8_t, 256> grey;
  tables(image.type(), gain, lut, grey);
  bins.create(image.size(), CV_8UC1);  // no reallocation when the cached buffer already fits
  int rows = image.rows;
  int cols = image.cols;
  if (image.isContinuous() && bins.isContinuous())
  {
    // One long row: fewer loop restarts, and the inner loop is all the compiler has to optimise.
    cols *= rows;
    rows = 1;
  }
  const int channels = image.channels();
  for (int y = 0; y < rows; ++y)
    binRow<false>(image.ptr<uint8_t>(y), cols, channels, lut, grey.data(), nullptr, bins.ptr<uint8_t>(y));
}

void HsiBinner::cellMeans(const cv::Mat& image, const std::array<uint8_t, 256>& weight, int cell, cv::Mat& out,
                          double gain) const
{
  if (cell < 1 || cell > 16)
    throw std::invalid_argument("HsiBinner::cellMeans: a cell is 1 to 16 pixels across, got " + std::to_string(cell));
  const uint8_t* lut = nullptr;
  std::array<uint8_t, 256> grey;
  tables(image.type(), gain, lut, grey);
  const int cols = image.cols / cell, rows = image.rows / cell;
  out.create(rows, cols, CV_8UC1);
  if (cols == 0 || rows == 0)
    return;
  const int channels = image.channels();
  const int width = cols * cell;
  // Per cell row: each image row's weights, summed down the cell's rows per column, then across each cell.
  std::vector<uint8_t> row(width);
  CellRows sums;
  for (int cy = 0; cy < rows; ++cy)
  {
    sums.start(width, cell);
    for (int y = cy * cell; y < (cy + 1) * cell; ++y)
    {
      binRow<true>(image.ptr<uint8_t>(y), width, channels, lut, grey.data(), weight.data(), row.data());
      sums.add(row.data());
    }
    sums.means(out.ptr<uint8_t>(cy));
  }
}

}  // namespace stereo_pf
