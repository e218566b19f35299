#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "capture/checks.h"
#include "capture/colour.h"
#include "capture/error.h"
#include "capture/image_io.h"
#include "evaluation/bench.h"
#include "lighting/frame/frame.h"
#include "lighting/techniques/registry.h"
#include "lighting/techniques/technique.h"

using nlohmann::json;

namespace mrgi::evaluation {

json knobsJson(const BenchConfig& c) { return lighting::usedKnobsJson(c.technique, c.knobs); }

std::vector<BenchConfig> sweepConfigs(const std::string& technique, bool quick, const lighting::KnobSet& base) {
  std::vector<BenchConfig> out;
  lighting::KnobSet defaults = base;
  lighting::completeKnobs(defaults);
  std::optional<lighting::TechniqueChoice> only;
  if (!technique.empty()) only = lighting::parseTechniqueChoice(technique, nullptr);
  auto wanted = [&](const lighting::TechniqueChoice& c) { return !only || *only == c; };
  // One knob at a time around the defaults, over its declared sweep values (booleans: the other value).
  auto sweep = [&](const lighting::TechniqueChoice& c, const lighting::KnobSet& start, const lighting::KnobGroup& g) {
    for (const lighting::KnobInfo& k : g.knobs)
      for (double v : quick ? k.quickSweep : k.sweep) {
        if (v == start.at(g.key).at(k.name)) continue;
        BenchConfig bc{c, start, g.key + "." + k.name};
        bc.knobs[g.key][k.name] = v;
        out.push_back(std::move(bc));
      }
  };
  for (const lighting::TechniqueInfo& t : lighting::techniques()) {
    const lighting::TechniqueChoice c = lighting::parseTechniqueChoice(t.name, nullptr);
    if (wanted(c)) {
      out.push_back({c, defaults, ""});
      sweep(c, defaults, lighting::frameKnobGroup());
      sweep(c, defaults, t.knobs);
    }
    for (const lighting::TechniqueAlias& a : t.aliases) {
      lighting::KnobSet k = defaults;
      const lighting::TechniqueChoice ac = lighting::parseTechniqueChoice(a.name, &k);
      if (wanted(ac)) out.push_back({ac, k, ""});
    }
  }
  // A real-pixel technique with another technique for the virtual object.
  for (const lighting::TechniqueInfo& r : lighting::techniques())
    for (const lighting::TechniqueInfo& v : lighting::techniques()) {
      if (&r == &v || !r.real || !v.virtualObject) continue;
      lighting::TechniqueChoice c = lighting::parseTechniqueRoles(r.name, v.name, nullptr);
      c.name = r.name + "+" + v.name;
      if (wanted(c)) out.push_back({c, defaults, ""});
    }
  return out;
}

namespace {
double errorOf(const json& r) { return 0.5 * (r.value("rel_error_delta", 0.0) + r.value("rel_error_virtual", 0.0)); }
/// What a configuration costs: its lighting ms a frame in replay over the room fused as the frames come (ms_replay),
/// or with every pass rerun each frame where a record has no such measure.
double msOf(const json& r) { return r.value("ms_replay", r.value("ms_lighting", 0.0)); }

/// Indices of the records no other record beats in both time and error, fastest first.
std::vector<size_t> paretoFront(const json& records, const std::vector<size_t>& subset) {
  std::vector<size_t> idx = subset;
  std::sort(idx.begin(), idx.end(), [&](size_t a, size_t b) {
    return msOf(records[a]) != msOf(records[b]) ? msOf(records[a]) < msOf(records[b])
                                                : errorOf(records[a]) < errorOf(records[b]);
  });
  std::vector<size_t> front;
  double best = INFINITY;
  for (size_t i : idx)
    if (errorOf(records[i]) < best) best = errorOf(records[i]), front.push_back(i);
  return front;
}

std::vector<size_t> allIndices(const json& records) {
  std::vector<size_t> v(records.size());
  for (size_t i = 0; i < v.size(); ++i) v[i] = i;
  return v;
}
}  // namespace

std::vector<BenchConfig> combinedConfigs(const std::vector<BenchConfig>& configs, const json& records) {
  std::vector<BenchConfig> out;
  for (size_t d = 0; d < configs.size() && d < records.size(); ++d) {
    if (!configs[d].varied.empty()) continue;
    const double ms = msOf(records[d]), err = errorOf(records[d]);
    // A one-knob row of the sweep for this technique (not its defaults, not a combination).
    const auto oneKnobRow = [&](size_t i) {
      const BenchConfig& c = configs[i];
      return !c.varied.empty() && c.varied.rfind("combined", 0) != 0 && c.technique == configs[d].technique &&
             c.technique.name == configs[d].technique.name;
    };
    std::map<std::string, size_t> fastest;  // per knob moved, the fastest free value's config
    for (size_t i = 0; i < configs.size() && i < records.size(); ++i) {
      const BenchConfig& c = configs[i];
      if (!oneKnobRow(i)) continue;
      // Each row is one measurement on a shared machine (the same work varies by 10-20 % between rows), so
      // some picks are noise; the combination is measured and only the front decides.
      if (!(msOf(records[i]) <= 0.9 * ms && errorOf(records[i]) <= 1.01 * err)) continue;
      const auto it = fastest.find(c.varied);
      if (it == fastest.end() || msOf(records[i]) < msOf(records[it->second])) fastest[c.varied] = i;
    }
    const auto withFreeMoves = [&](BenchConfig c, const std::string& except) {
      for (const auto& [varied, i] : fastest) {
        if (varied == except) continue;
        const std::string group = varied.substr(0, varied.find('.')), knob = varied.substr(varied.find('.') + 1);
        c.knobs[group][knob] = configs[i].knobs.at(group).at(knob);
      }
      return c;
    };
    if (fastest.size() >= 2) out.push_back(withFreeMoves({configs[d].technique, configs[d].knobs, "combined"}, ""));
    // The technique's most accurate one-knob row, at least 5 % more accurate than its defaults (the step balanced
    // asks for), with the free moves of the other knobs: what accuracy costs once the free savings are taken too.
    size_t best = configs.size();
    for (size_t i = 0; i < configs.size() && i < records.size(); ++i) {
      if (!oneKnobRow(i) || !(errorOf(records[i]) <= 0.95 * err)) continue;
      if (best == configs.size() || errorOf(records[i]) < errorOf(records[best])) best = i;
    }
    // None without such a row, or without a free move of another knob.
    if (best == configs.size() || fastest.size() <= fastest.count(configs[best].varied)) continue;
    out.push_back(
        withFreeMoves({configs[best].technique, configs[best].knobs, "combined accurate"}, configs[best].varied));
  }
  return out;
}

json choosePresets(const json& records) {
  if (records.empty()) return json::object();
  const auto front = paretoFront(records, allIndices(records));
  double eMin = INFINITY, msMin = INFINITY;
  size_t accurate = front.front();
  for (size_t i : front) {
    msMin = std::min(msMin, std::max(msOf(records[i]), 1e-6));
    if (errorOf(records[i]) < eMin) eMin = errorOf(records[i]), accurate = i;
  }
  eMin = std::max(eMin, 1e-9);
  size_t fast = accurate, balanced = accurate;
  for (size_t i : front)
    if (errorOf(records[i]) <= 2 * eMin) {
      fast = i;
      break;  // the front is fastest first
    }
  // Balanced: the best trade (least ms/ms_min x err/err_min) among the front's records at least 5 % more
  // accurate than fast (a smaller gain is within what one run measures: rows doing the same work differ in
  // the third digit), so that the two differ whenever the front offers more accuracy (fast when it does not).
  balanced = fast;
  double bestScore = INFINITY;
  for (size_t i : front) {
    if (!(errorOf(records[i]) <= 0.95 * errorOf(records[fast]))) continue;
    const double score = std::max(msOf(records[i]), 1e-6) / msMin * (errorOf(records[i]) / eMin);
    if (score < bestScore) bestScore = score, balanced = i;
  }
  return {{"fast", records[fast]}, {"balanced", records[balanced]}, {"accurate", records[accurate]}};
}

json presetDifferences(const json& presets) {
  json out = json::object();
  const std::pair<const char*, const char*> pairs[] = {{"fast", "balanced"}, {"balanced", "accurate"}};
  for (const auto& [a, b] : pairs) {
    if (!presets.contains(a) || !presets.contains(b) || presets[a] == presets[b]) continue;
    if (!presets[a].contains("sessions") || !presets[b].contains("sessions")) continue;
    json sessions = json::array();
    bool resolved = true;
    for (const json& sa : presets[a]["sessions"])
      for (const json& sb : presets[b]["sessions"]) {
        if (sa["session"] != sb["session"] || !sa.contains("rel_rms_delta_unbiased") ||
            !sb.contains("rel_rms_delta_unbiased"))
          continue;
        const json& ua = sa["rel_rms_delta_unbiased"];
        const json& ub = sb["rel_rms_delta_unbiased"];
        const bool overlap =
            ua["lo"].get<double>() <= ub["hi"].get<double>() && ub["lo"].get<double>() <= ua["hi"].get<double>();
        resolved = resolved && !overlap;
        sessions.push_back({{"session", sa["session"]},
                            {"a", {ua["value"], ua["lo"], ua["hi"]}},
                            {"b", {ub["value"], ub["lo"], ub["hi"]}},
                            {"overlap", overlap}});
      }
    if (sessions.empty()) continue;
    out[std::string(a) + "_vs_" + b] = {{"resolved", resolved}, {"sessions", sessions}};
  }
  return out;
}

cv::Rect galleryCrop(const cv::Mat& virtualMask, double grow) {
  const cv::Rect whole(0, 0, virtualMask.cols, virtualMask.rows);
  std::vector<cv::Point> on;
  cv::findNonZero(virtualMask, on);
  if (on.empty()) return whole;
  const cv::Rect box = cv::boundingRect(on);
  const int dx = static_cast<int>(std::lround(grow * box.width)), dy = static_cast<int>(std::lround(grow * box.height));
  return cv::Rect(box.x - dx, box.y - dy, box.width + 2 * dx, box.height + 2 * dy) & whole;
}

namespace {
/// The real-pixel delta as grey (0.5 = no change, 0 or 1 at `scale` either way, square-root scale), the
/// objects' pixels blue.
cv::Mat deltaTile(const cv::Mat& delta, int channels, const cv::Mat& virtualMask, double scale) {
  cv::Mat out(delta.size(), CV_8UC3);
  for (int y = 0; y < delta.rows; ++y)
    for (int x = 0; x < delta.cols; ++x) {
      if (virtualMask.at<uchar>(y, x)) {
        out.at<cv::Vec3b>(y, x) = {60, 90, 200};
        continue;
      }
      const float* d = delta.ptr<float>(y) + channels * x;
      const double lum = capture::luminance(cv::Vec3d(d[0], d[1], d[2]));
      // Square-root scale: the faint, wide part of a shadow shows beside its dark core.
      const double t = std::min(1.0, std::sqrt(std::abs(lum) / scale));
      const auto g = static_cast<uchar>(std::clamp(127.5 + (lum < 0 ? -127.5 : 127.5) * t, 0.0, 255.0));
      out.at<cv::Vec3b>(y, x) = {g, g, g};
    }
  return out;
}
}  // namespace

cv::Mat galleryImage(const std::string& title, const cv::Mat& referenceComposite, const cv::Mat& referenceDelta,
                     const cv::Mat& virtualMask, const std::vector<GalleryRow>& rows) {
  const cv::Rect crop = galleryCrop(virtualMask);
  const cv::Mat mask = virtualMask(crop);
  // The scale: the reference's largest change in the crop (its darkest shadow, usually).
  double scale = 1e-6;
  const cv::Mat ref = referenceDelta(crop);
  for (int y = 0; y < ref.rows; ++y)
    for (int x = 0; x < ref.cols; ++x)
      if (!mask.at<uchar>(y, x))
        scale = std::max(scale, std::abs(capture::luminance(cv::Vec3d(ref.at<cv::Vec3f>(y, x)))));
  const double zoom = std::max(1.0, 160.0 / crop.height);
  const cv::Size tile(static_cast<int>(std::lround(crop.width * zoom)),
                      static_cast<int>(std::lround(crop.height * zoom)));
  // Cells (a label over composite | delta) in a grid of three columns, the reference first.
  const int label = 20, gap = 8, header = 48, cols = 3;
  const int cellW = 2 * tile.width + gap, cellH = label + tile.height;
  const int n = static_cast<int>(rows.size()) + 1, gridRows = (n + cols - 1) / cols;
  cv::Mat out(header + gridRows * (cellH + gap) + gap, gap + cols * (cellW + gap), CV_8UC3, cv::Scalar(255, 255, 255));
  cv::putText(out, title, {gap, 18}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::putText(out,
              "composite | real-pixel delta, square-root scale: grey = none, black = -" + capture::formatNumber(scale) +
                  " W/m^2/sr (the reference's darkest), objects blue",
              {gap, 38}, cv::FONT_HERSHEY_SIMPLEX, 0.42, cv::Scalar(60, 60, 60), 1, cv::LINE_AA);
  auto place = [&](int cell, const std::string& text, const cv::Mat& composite, const cv::Mat& delta) {
    const int x = gap + (cell % cols) * (cellW + gap), y = header + (cell / cols) * (cellH + gap);
    cv::putText(out, text, {x, y + 14}, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    cv::Mat a, b;
    cv::resize(composite(crop), a, tile, 0, 0, cv::INTER_NEAREST);
    cv::resize(delta, b, tile, 0, 0, cv::INTER_NEAREST);
    a.copyTo(out(cv::Rect(x, y + label, tile.width, tile.height)));
    b.copyTo(out(cv::Rect(x + tile.width + gap, y + label, tile.width, tile.height)));
  };
  place(0, "reference (path traced)", referenceComposite, deltaTile(ref, 3, mask, scale));
  for (size_t i = 0; i < rows.size(); ++i)
    place(static_cast<int>(i) + 1, rows[i].label, rows[i].composite,
          deltaTile(rows[i].shade(crop), rows[i].shade.channels(), mask, scale));
  return out;
}

const char* const kCsvHeader =
    "technique,varied,knobs,ms_total,ms_lighting,ms_view,ms_replay,gpu_mb,rmse_delta,rel_error_delta,"
    "rel_error_delta_near,rel_error_virtual,ssim,flicker";
const char* const kCsvSignature = "technique,varied,knobs,ms_total,ms_lighting,";

void writeCsv(const std::string& path, const json& records) {
  std::ostringstream s;
  s << kCsvHeader << "\n";
  for (const auto& r : records) {
    std::string knobs;
    for (const auto& [k, v] : r["knobs"].items()) knobs += (knobs.empty() ? "" : ";") + k + "=" + v.dump();
    s << r["technique"].get<std::string>() << "," << r.value("varied", "") << "," << knobs << "," << r["ms_total"]
      << "," << r["ms_lighting"] << "," << r["ms_view"] << "," << r["ms_replay"] << "," << r["gpu_mb"] << ","
      << r["rmse_delta"] << "," << r["rel_error_delta"] << "," << r.value("rel_error_delta_near", 0.0) << ","
      << r["rel_error_virtual"] << "," << r["ssim"] << "," << r["flicker"] << "\n";
  }
  capture::writeFileAtomically(path, s.str());
}

namespace {

std::string base64(const std::vector<uchar>& bytes) {
  static const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (size_t i = 0; i < bytes.size(); i += 3) {
    const uint32_t n = (uint32_t(bytes[i]) << 16) | (i + 1 < bytes.size() ? uint32_t(bytes[i + 1]) << 8 : 0) |
                       (i + 2 < bytes.size() ? uint32_t(bytes[i + 2]) : 0);
    out += table[(n >> 18) & 63];
    out += table[(n >> 12) & 63];
    out += i + 1 < bytes.size() ? table[(n >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? table[n & 63] : '=';
  }
  return out;
}

/// A colour and a marker per series (technique spelling), stable for a name: a technique alone takes its
/// registry index, a pair "real+virtual" 6 + its ordered pair's index; index i draws colour i mod 10 with
/// marker i / 10 mod 4 (circle, square, triangle, diamond): 40 series before two look alike.
struct SeriesStyle {
  const char* colour;
  int marker;
};
SeriesStyle styleOf(const std::string& series) {
  static const char* palette[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                                  "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};
  const auto& all = lighting::techniques();
  const auto indexOf = [&](const std::string& name) -> int {
    for (size_t i = 0; i < all.size(); ++i)
      if (all[i].name == name) return static_cast<int>(i);
    return -1;
  };
  const int n = static_cast<int>(all.size());
  int index = indexOf(series);
  if (index < 0) {
    const auto plus = series.find('+');
    const int a = plus == std::string::npos ? -1 : indexOf(series.substr(0, plus)),
              b = plus == std::string::npos ? -1 : indexOf(series.substr(plus + 1));
    index = a >= 0 && b >= 0 && a != b ? n + a * (n - 1) + (b < a ? b : b - 1)
                                       : n * n + static_cast<int>(std::hash<std::string>()(series) % 40);
  }
  return {palette[index % 10], (index / 10) % 4};
}
const char* colourOf(const std::string& series) { return styleOf(series).colour; }

/// An SVG marker of `series`'s style at (x, y), `inner` inside its element (a tooltip).
std::string markerSvg(double x, double y, const std::string& series, const std::string& inner = {},
                      double opacity = 0.8) {
  const SeriesStyle st = styleOf(series);
  std::ostringstream s;
  const std::string fill = std::string("fill='") + st.colour + "' fill-opacity='" + std::to_string(opacity) + "'";
  switch (st.marker) {
    case 0:
      s << "<circle cx='" << x << "' cy='" << y << "' r='4' " << fill << ">";
      return s.str() + inner + "</circle>";
    case 1:
      s << "<rect x='" << x - 3.5 << "' y='" << y - 3.5 << "' width='7' height='7' " << fill << ">";
      return s.str() + inner + "</rect>";
    case 2:
      s << "<polygon points='" << x << "," << y - 5 << " " << x - 4.5 << "," << y + 3.5 << " " << x + 4.5 << ","
        << y + 3.5 << "' " << fill << ">";
      return s.str() + inner + "</polygon>";
    default:
      s << "<polygon points='" << x << "," << y - 5 << " " << x + 5 << "," << y << " " << x << "," << y + 5 << " "
        << x - 5 << "," << y << "' " << fill << ">";
      return s.str() + inner + "</polygon>";
  }
}

std::string fmt(double v, int digits = 3) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}

std::string esc(const std::string& s) {
  std::string o;
  for (char c : s)
    o += c == '<' ? "&lt;" : c == '>' ? "&gt;" : c == '&' ? "&amp;" : c == '"' ? "&quot;" : std::string(1, c);
  return o;
}

/// Round tick values over [lo, hi] (log10 of the values when `log`): 1-2-5 steps, or 1-2-5 within each decade
/// on a log axis (decades alone when there are many), at least two; with the digits that tell them apart.
std::vector<std::pair<double, std::string>> niceTicks(double lo, double hi, bool log) {
  std::vector<double> values;
  const auto linear = [&](double a, double b) {
    const double range = b - a;
    if (!(range > 0) || !std::isfinite(range)) return;
    double step = std::pow(10.0, std::floor(std::log10(range / 4)));
    for (const double m : {1.0, 2.0, 5.0, 10.0})
      if (range / (step * m) <= 6) {
        step *= m;
        break;
      }
    for (double v = std::ceil(a / step) * step; v <= b + 1e-9 * step; v += step)
      values.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
  };
  if (log) {
    for (const std::vector<double>& mantissas : {std::vector<double>{1, 2, 5}, std::vector<double>{1}}) {
      values.clear();
      for (int k = static_cast<int>(std::floor(lo)); k <= static_cast<int>(std::ceil(hi)); ++k)
        for (const double m : mantissas) {
          const double v = m * std::pow(10.0, k), l = std::log10(v);
          if (l >= lo && l <= hi) values.push_back(v);
        }
      if (values.size() <= 7) break;
    }
    if (values.size() < 2) {
      values.clear();
      linear(std::pow(10.0, lo), std::pow(10.0, hi));
    }
  } else {
    linear(lo, hi);
  }
  // Digits enough to tell neighbours apart.
  int digits = 3;
  for (size_t i = 1; i < values.size(); ++i) {
    const double gap = values[i] - values[i - 1], mag = std::max(std::abs(values[i]), std::abs(values[i - 1]));
    if (gap > 0) digits = std::max(digits, static_cast<int>(std::ceil(std::log10(mag / gap))) + 1);
  }
  digits = std::min(digits, 8);
  std::vector<std::pair<double, std::string>> out;
  for (const double v : values) {
    char b[64];
    std::snprintf(b, sizeof b, "%.*g", digits, v);
    out.push_back({v, b});
  }
  return out;
}

/// A scatter plot with log-scaled axes; each point has a tooltip; `lines` connects points per series.
struct Plot {
  Plot(std::string t, std::string x, std::string y) : title(std::move(t)), xLabel(std::move(x)), yLabel(std::move(y)) {}
  std::string title, xLabel, yLabel;
  bool logX = true, logY = true;
  struct Point {
    double x, y;
    std::string series, tip;
  };
  std::vector<Point> points;
  std::map<std::string, std::vector<std::pair<double, double>>> lines;
  std::vector<std::string> notes;

  std::string svg() const {
    // The legend as wide as its longest name (about 6.2 px a character at 11 px), so no name is cut.
    size_t longest = 0;
    for (const auto& p : points) longest = std::max(longest, p.series.size());
    for (const auto& n : notes) longest = std::max(longest, n.size());
    const double R = std::max(150.0, 32 + 6.2 * static_cast<double>(longest)), W = 410 + R, H = 340, L = 70, T = 30,
                 B = 50;
    double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
    auto tx = [&](double v) { return logX ? std::log10(std::max(v, 1e-9)) : v; };
    auto ty = [&](double v) { return logY ? std::log10(std::max(v, 1e-9)) : v; };
    for (const auto& p : points)
      x0 = std::min(x0, tx(p.x)), x1 = std::max(x1, tx(p.x)), y0 = std::min(y0, ty(p.y)), y1 = std::max(y1, ty(p.y));
    if (!(x1 > x0)) x0 -= 0.5, x1 += 0.5;
    if (!(y1 > y0)) y0 -= 0.5, y1 += 0.5;
    const double px = 0.05 * (x1 - x0), py = 0.08 * (y1 - y0);
    x0 -= px, x1 += px, y0 -= py, y1 += py;
    auto X = [&](double v) { return L + (tx(v) - x0) / (x1 - x0) * (W - L - R); };
    auto Y = [&](double v) { return H - B - (ty(v) - y0) / (y1 - y0) * (H - T - B); };
    std::ostringstream s;
    // With its viewBox a plot wider than the page (a very long legend name) scales down instead of running off.
    s << "<svg xmlns='http://www.w3.org/2000/svg' width='" << W << "' height='" << H << "' viewBox='0 0 " << W << " "
      << H << "' font-family='sans-serif' font-size='11'>";
    s << "<text x='" << W / 2 << "' y='16' text-anchor='middle' font-weight='bold'>" << esc(title) << "</text>";
    s << "<rect x='" << L << "' y='" << T << "' width='" << W - L - R << "' height='" << H - T - B
      << "' fill='none' stroke='#888'/>";
    for (const auto& [v, text] : niceTicks(x0, x1, logX)) {  // axis ticks at round values
      const double sx = X(v);
      s << "<line x1='" << sx << "' y1='" << H - B << "' x2='" << sx << "' y2='" << H - B + 4 << "' stroke='#888'/>";
      s << "<text class='xtick' x='" << sx << "' y='" << H - B + 15 << "' text-anchor='middle'>" << text << "</text>";
    }
    for (const auto& [v, text] : niceTicks(y0, y1, logY)) {
      const double sy = Y(v);
      s << "<line x1='" << L - 4 << "' y1='" << sy << "' x2='" << L << "' y2='" << sy << "' stroke='#888'/>";
      s << "<text class='ytick' x='" << L - 6 << "' y='" << sy + 4 << "' text-anchor='end'>" << text << "</text>";
    }
    s << "<text x='" << (L + W - R) / 2 << "' y='" << H - 12 << "' text-anchor='middle'>" << esc(xLabel) << "</text>";
    s << "<text transform='translate(14," << (T + H - B) / 2 << ") rotate(-90)' text-anchor='middle'>" << esc(yLabel)
      << "</text>";
    for (const auto& [series, pts] : lines) {
      s << "<polyline fill='none' stroke='" << colourOf(series) << "' stroke-width='1.5' points='";
      for (const auto& [x, y] : pts) s << X(x) << "," << Y(y) << " ";
      s << "'/>";
    }
    std::set<std::string> seen;
    for (const auto& p : points) {
      s << markerSvg(X(p.x), Y(p.y), p.series, "<title>" + esc(p.tip) + "</title>", 0.75);
      seen.insert(p.series);
    }
    double ly = T + 10;
    for (const auto& series : seen) {
      s << markerSvg(W - R + 14, ly - 4, series, "<title>legend</title>", 1.0) << "<text class='legend' x='"
        << W - R + 22 << "' y='" << ly << "'>" << esc(series) << "</text>";
      ly += 16;
    }
    for (const auto& n : notes) {
      s << "<text x='" << W - R + 8 << "' y='" << ly + 6 << "'>" << esc(n) << "</text>";
      ly += 14;
    }
    s << "</svg>";
    return s.str();
  }
};

/// Least-squares slope of log y against log x.
double logSlope(const std::vector<std::pair<double, double>>& xy) {
  if (xy.size() < 2) return NAN;
  double mx = 0, my = 0;
  for (const auto& [x, y] : xy) mx += std::log(x), my += std::log(y);
  mx /= xy.size(), my /= xy.size();
  double sxy = 0, sxx = 0;
  for (const auto& [x, y] : xy)
    sxy += (std::log(x) - mx) * (std::log(y) - my), sxx += (std::log(x) - mx) * (std::log(x) - mx);
  return sxx > 0 ? sxy / sxx : NAN;
}

/// The value of knob `v` ("lpv.resolution") in a record's knobs, or null.
json knobValue(const json& r, const std::string& v) {
  const size_t dot = v.find('.');
  if (dot == std::string::npos) return nullptr;
  const json& k = r["knobs"];
  const std::string g = v.substr(0, dot), n = v.substr(dot + 1);
  return k.contains(g) && k[g].contains(n) ? k[g][n] : json(nullptr);
}

/// The value of the knob a record varies, or null.
json variedValue(const json& r) { return knobValue(r, r.value("varied", "")); }

/// "dlpv frame.rsm_size=64" or "dlpv defaults".
std::string labelOf(const json& r) {
  const std::string v = r.value("varied", "");
  const json value = variedValue(r);
  return r["technique"].get<std::string>() +
         (v.empty() ? " defaults" : " " + v + (value.is_null() ? "" : "=" + value.dump()));
}

std::string tipOf(const json& r) {
  return r["technique"].get<std::string>() + " " + r["knobs"].dump() + "\nms " + fmt(msOf(r)) + ", error " +
         fmt(errorOf(r));
}

}  // namespace

void writeHtml(const std::string& path, const json& doc, const std::vector<ReportImage>& images) {
  const json& records = doc["records"];
  std::ostringstream h;
  h << "<!DOCTYPE html><html><head><meta charset='utf-8'><meta name=\"generator\" content=\"mrgi bench\"><title>mrgi "
       "bench</title><style>"
       "body{font-family:sans-serif;max-width:1200px;margin:20px auto;padding:0 "
       "16px}table{border-collapse:collapse;font-size:12px}"
       "td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}td.l{text-align:left}"
       "figure{display:inline-block;margin:6px;vertical-align:top}figcaption{font-size:12px;white-space:normal}"
       "div.wide{overflow-x:auto;max-width:100%}svg{max-width:100%;height:auto}details summary{cursor:pointer}details "
       "pre{text-align:left;margin:2px}"
       "</style></head><body>";
  std::string sessionText;
  if (doc.contains("session"))
    for (const auto& sname : doc["session"].is_array() ? doc["session"] : json::array({doc["session"]}))
      sessionText +=
          (sessionText.empty() ? "" : ", ") + std::string("<code>") + esc(sname.get<std::string>()) + "</code>";
  h << "<h1>mrgi bench</h1><p>Sessions " << sessionText
    << " (every measure below is the mean over the sessions), scene <code>" << esc(doc.value("scene", ""))
    << "</code>, " << doc.value("frames", 0) << " frames, renderer <code>" << esc(doc.value("gl", ""))
    << "</code>. Reference: path traced, " << doc["reference"].value("spp", 0) << " spp, "
    << doc["reference"].value("bounces", 0) << " bounces, frames " << doc["reference"]["frames"].dump()
    << " (its own noise, two seeds / sqrt 2: relative error "
    << fmt(doc["reference"].value("noise_rel_error_delta", 0.0)) << " on the delta, "
    << fmt(doc["reference"].value("noise_rel_error_virtual", 0.0))
    << " on the virtual radiance: the floor under every error below";
  for (const auto& ref : doc.value("references", json::array()))
    h << "; " << esc(ref.value("session", "")) << ": " << fmt(ref.value("noise_rel_error_delta", 0.0)) << " / "
      << fmt(ref.value("noise_rel_error_virtual", 0.0));
  h << ").</p><p>Marker tracking against the ground-truth camera poses (what --pose marker would add): ";
  for (const auto& ref : doc.value("references", json::array()))
    if (ref.contains("marker_pose_error") && ref["marker_pose_error"].is_object()) {
      const json& m = ref["marker_pose_error"];
      h << esc(ref.value("session", "")) << " (" << m["resolution"][0].get<int>() << "x"
        << m["resolution"][1].get<int>() << "): " << fmt(m.value("position_mm_mean", 0.0)) << " mm / "
        << fmt(m.value("rotation_deg_mean", 0.0)) << "&deg; mean, " << fmt(m.value("position_mm_max", 0.0)) << " mm / "
        << fmt(m.value("rotation_deg_max", 0.0)) << "&deg; max, " << m.value("lost", 0) << " frames lost; ";
    }
  h << "</p><p>Camera tracking against the ground-truth poses (ATE RMSE, RPE per frame, frames tracked): ";
  for (const auto& ref : doc.value("references", json::array()))
    if (ref.contains("tracking") && ref["tracking"].is_object()) {
      h << esc(ref.value("session", "")) << ": ";
      for (const auto& [mode, t] : ref["tracking"].items())
        h << esc(mode) << " " << fmt(t.value("ate_rmse_mm", 0.0)) << " mm, " << fmt(t.value("rpe_rmse_mm", 0.0))
          << " mm / " << fmt(t.value("rpe_rmse_deg", 0.0)) << "&deg;, " << t.value("tracked", 0) << " of "
          << t.value("frames", 0) << "; ";
    }
  if (doc.contains("tracking_pixels") && doc["tracking_pixels"].is_object()) {
    const json& tp = doc["tracking_pixels"];
    h << "</p><p>Tracking in pixels on " << esc(tp.value("sequence", "")) << " (" << tp.value("frames", 0)
      << " real frames: the tags placed from frame 0 and drawn with each way of tracking; RMS / 95th percentile, "
         "frames tracked, ms a frame): ";
    for (const auto& r : tp.value("rows", json::array()))
      h << esc(r.value("poses", "")) << " " << fmt(r.value("rms_px", 0.0)) << " / " << fmt(r.value("p95_px", 0.0))
        << " px, " << r.value("tracked", 0) << " of " << r.value("frames", 0) << ", "
        << fmt(r.value("ms_per_frame", 0.0)) << " ms; ";
  }
  h << "</p><p>";
  h << "Times are means over the frames after the first (ms, the larger of CPU and GPU time per stage); "
       "error = mean of the relative errors of the real-pixel delta and the virtual radiance.</p>";

  // Pareto fronts.
  Plot pareto("Time vs error (lines: Pareto front per technique)", "lighting ms per frame in replay",
              "error (relative)");
  std::map<std::string, std::vector<size_t>> byTechnique;
  for (size_t i = 0; i < records.size(); ++i) {
    byTechnique[records[i]["technique"]].push_back(i);
    pareto.points.push_back(
        {msOf(records[i]), std::max(errorOf(records[i]), 1e-6), records[i]["technique"], tipOf(records[i])});
  }
  for (const auto& [t, idx] : byTechnique)
    for (size_t i : paretoFront(records, idx))
      pareto.lines[t].push_back({msOf(records[i]), std::max(errorOf(records[i]), 1e-6)});
  Plot ssim("Composite SSIM vs time", "lighting ms per frame in replay", "1 - SSIM");
  Plot flicker("Temporal flicker of the real-pixel delta", "lighting ms per frame in replay", "flicker (relative)");
  for (const auto& r : records) {
    ssim.points.push_back({msOf(r), std::max(1.0 - r.value("ssim", 0.0), 1e-6), r["technique"], tipOf(r)});
    if (r.value("flicker", 0.0) > 0)
      flicker.points.push_back({msOf(r), r["flicker"].get<double>(), r["technique"], tipOf(r)});
  }
  h << "<h2>Speed against accuracy</h2>" << pareto.svg() << ssim.svg();
  if (!flicker.points.empty()) h << flicker.svg();

  // Scaling: per technique and swept numeric knob, lighting time against the knob's value (with the
  // defaults), and the fitted slope of log time against log value.
  std::map<std::string, Plot> scaling;
  std::map<std::string, std::vector<std::pair<double, double>>> scalingXY;
  for (const auto& r : records) {
    const json v = variedValue(r);
    if (!v.is_number() || v.get<double>() <= 0) continue;
    const std::string key = r["technique"].get<std::string>() + ": " + r["varied"].get<std::string>();
    auto [it, inserted] =
        scaling.try_emplace(key, key, r["varied"].get<std::string>(), "lighting ms per frame in replay");
    it->second.points.push_back({v.get<double>(), msOf(r), r["technique"], tipOf(r)});
    scalingXY[key].push_back({v.get<double>(), msOf(r)});
  }
  for (const auto& r : records) {  // each curve's defaults point
    if (!r.value("varied", "").empty()) continue;
    for (auto& [key, plot] : scaling) {
      if (key.rfind(r["technique"].get<std::string>() + ": ", 0) != 0) continue;
      const std::string knob = key.substr(key.find(": ") + 2);
      const json v = knobValue(r, knob);
      if (!v.is_number() || v.get<double>() <= 0) continue;
      plot.points.push_back({v.get<double>(), msOf(r), r["technique"], tipOf(r)});
      scalingXY[key].push_back({v.get<double>(), msOf(r)});
    }
  }
  if (!scaling.empty()) {
    h << "<h2>Scaling</h2><p>Lighting time against each swept knob; fitted slope of log time against log value "
         "(1 = linear).</p>";
    for (auto& [key, plot] : scaling) {
      if (plot.points.size() < 2) continue;
      plot.notes.push_back("slope " + fmt(logSlope(scalingXY[key]), 2));
      h << plot.svg();
    }
  }

  // Stage-time stacks.
  std::set<std::string> stageNames;
  for (const auto& r : records)
    for (const auto& [k, v] : r["ms_stages"].items()) stageNames.insert(k);
  static const char* palette[] = {"#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f", "#edc948", "#b07aa1",
                                  "#ff9da7", "#9c755f", "#bab0ac", "#17becf", "#bcbd22", "#8c564b", "#7f7f7f"};
  std::map<std::string, const char*> stageColour;
  size_t ci = 0;
  for (const auto& n : stageNames) stageColour[n] = palette[ci++ % 14];
  double maxTotal = 1e-9;
  for (const auto& r : records) maxTotal = std::max(maxTotal, r.value("ms_total", 0.0));
  // 930 px wide: within the page's 968 px of content at a 1,000 px window, with room after the longest bar
  // for its total in whole milliseconds (a slow machine's 12345 as much as a fast one's 296).
  const double rowH = 16, labelW = 230, barW = 640, svgW = labelW + barW + 60;
  const int legendRows = static_cast<int>((stageNames.size() + 6) / 7);
  const double svgH = rowH * static_cast<double>(records.size()) + 30 + 16 * legendRows;
  h << "<h2>Stage times</h2><p>Mean ms per frame and stage (hover for values).</p><svg "
       "xmlns='http://www.w3.org/2000/svg' width='"
    << svgW << "' height='" << svgH << "' viewBox='0 0 " << svgW << " " << svgH
    << "' font-family='sans-serif' font-size='10'>";
  for (size_t i = 0; i < records.size(); ++i) {
    const json& r = records[i];
    const double y = 10 + i * rowH;
    h << "<text x='" << labelW - 4 << "' y='" << y + 11 << "' text-anchor='end'>" << esc(labelOf(r)) << "</text>";
    double x = labelW;
    for (const auto& [k, v] : r["ms_stages"].items()) {
      const double w = v.get<double>() / maxTotal * barW;
      h << "<rect x='" << x << "' y='" << y << "' width='" << w << "' height='" << rowH - 3 << "' fill='"
        << stageColour[k] << "'><title>" << esc(k) << " " << fmt(v.get<double>()) << " ms</title></rect>";
      x += w;
    }
    char total[32];
    std::snprintf(total, sizeof total, "%.0f", std::min(r.value("ms_total", 0.0), 99999.0));
    h << "<text x='" << x + 3 << "' y='" << y + 11 << "'>" << total << "</text>";
  }
  int li = 0;
  for (const auto& [n, c] : stageColour) {
    const double lx = 10 + (li % 7) * 125, ly = 20 + rowH * records.size() + 16 * (li / 7);
    h << "<rect x='" << lx << "' y='" << ly << "' width='10' height='10' fill='" << c << "'/><text x='" << lx + 13
      << "' y='" << ly + 9 << "'>" << esc(n) << "</text>";
    ++li;
  }
  h << "</svg>";

  // Presets and the table.
  if (doc.contains("presets") && !doc["presets"].empty()) {
    h << "<h2>Presets</h2><div class='wide'><table><tr><th>preset</th><th>technique</th><th "
         "class='l'>knobs</th><th>lighting "
         "ms in replay</th><th>error</th></tr>";
    for (const char* name : {"fast", "balanced", "accurate"}) {
      const json& p = doc["presets"][name];
      h << "<tr><td class='l'>" << name << "</td><td class='l'>" << esc(p["technique"].get<std::string>())
        << "</td><td class='l'><details><summary>knobs</summary><pre>" << esc(p["knobs"].dump(1))
        << "</pre></details></td><td>" << fmt(msOf(p)) << "</td><td>" << fmt(errorOf(p)) << "</td></tr>";
    }
    h << "</table></div>";
  }
  // Tables scroll within the page at narrow widths; each row's knobs fold away.
  h << "<h2>All configurations</h2><div class='wide'><table><tr><th>technique</th><th>varied</th><th "
       "class='l'>knobs</th><th>ms "
       "total</th>"
       "<th>ms lighting, every pass</th><th>ms lighting, per view</th><th>ms lighting in replay</th><th>GPU "
       "MB</th><th>RMSE delta</th><th>rel. err. delta</th><th>rel. err. "
       "virtual</th><th>SSIM</th>"
       "<th>flicker</th></tr>";
  for (const auto& r : records)
    h << "<tr><td class='l'>" << esc(r["technique"].get<std::string>()) << "</td><td class='l'>"
      << esc(r.value("varied", "")) << "</td><td class='l'><details><summary>knobs</summary><pre>"
      << esc(r["knobs"].dump(1)) << "</pre></details></td><td>" << fmt(r["ms_total"].get<double>()) << "</td><td>"
      << fmt(r["ms_lighting"].get<double>()) << "</td><td>" << fmt(r["ms_view"].get<double>()) << "</td><td>"
      << fmt(msOf(r)) << "</td><td>" << fmt(r["gpu_mb"].get<double>()) << "</td><td>"
      << fmt(r["rmse_delta"].get<double>()) << "</td><td>" << fmt(r["rel_error_delta"].get<double>()) << "</td><td>"
      << fmt(r["rel_error_virtual"].get<double>()) << "</td><td>" << fmt(r["ssim"].get<double>(), 4) << "</td><td>"
      << fmt(r["flicker"].get<double>()) << "</td></tr>";
  h << "</table></div>";

  // Per session, with the whole pipeline against a synthetic session's own true reference where it has one.
  h << "<h2>Per session</h2><p>Technique error: against the path-traced reference of the inputs the pipeline sees "
       "(measured depth, estimated albedo). Whole pipeline: against the synthetic session's true reference composites "
       "(the true room, albedos and lights), so depth noise, albedo and light estimation count too. Delta RMS: the "
       "real-pixel "
       "delta's relative RMS error without the reference's noise (two renders), with its 95 % interval. Shadow: within "
       "three "
       "object radii, the darkening's energy over the reference's / the near L1 of the blurred delta.</p>"
       "<div class='wide'><table><tr><th>technique</th><th>varied</th><th class='l'>session</th><th>ms "
       "lighting in replay</th><th>rel. err. "
       "delta</th>"
       "<th>delta RMS [95 %]</th><th>shadow</th>"
       "<th>rel. err. virtual</th><th>SSIM</th><th>flicker</th><th>whole: delta</th><th>whole: shadow</th><th>whole: "
       "virtual</th>"
       "<th>whole: SSIM</th></tr>";
  for (const auto& r : records)
    for (const auto& p : r.value("sessions", json::array())) {
      h << "<tr><td class='l'>" << esc(r["technique"].get<std::string>()) << "</td><td class='l'>"
        << esc(r.value("varied", "")) << "</td><td class='l'>" << esc(p.value("session", "")) << "</td><td>"
        << fmt(msOf(p)) << "</td><td>" << fmt(p["rel_error_delta"].get<double>()) << "</td><td>";
      if (p.contains("rel_rms_delta_unbiased")) {
        const json& u = p["rel_rms_delta_unbiased"];
        h << fmt(u["value"].get<double>()) << " [" << fmt(u["lo"].get<double>()) << ", " << fmt(u["hi"].get<double>())
          << "]";
      } else {
        h << "-";
      }
      auto shadow = [&](const json& record) {
        if (!record.contains("shadow")) return std::string("-");
        return fmt(record["shadow"]["energy"].get<double>()) + " / " + fmt(record["shadow"]["near_l1"].get<double>());
      };
      h << "</td><td>" << shadow(p) << "</td><td>" << fmt(p["rel_error_virtual"].get<double>()) << "</td><td>"
        << fmt(p["ssim"].get<double>(), 4) << "</td><td>" << fmt(p["flicker"].get<double>()) << "</td>";
      if (p.contains("whole_pipeline")) {
        const json& w = p["whole_pipeline"];
        h << "<td>" << fmt(w["rel_error_delta"].get<double>()) << "</td><td>" << shadow(w) << "</td><td>"
          << fmt(w["rel_error_virtual"].get<double>()) << "</td><td>" << fmt(w["ssim"].get<double>(), 4) << "</td>";
      } else {
        h << "<td>-</td><td>-</td><td>-</td><td>-</td>";
      }
      h << "</tr>";
    }
  h << "</table></div>";

  if (!images.empty()) {
    h << "<h2>Images</h2>";
    const auto figure = [&](const ReportImage& im) {
      cv::Mat bgr;
      cv::cvtColor(im.rgb, bgr, cv::COLOR_RGB2BGR);
      std::vector<uchar> png;
      cv::imencode(".png", bgr, png);
      // As wide as its image, so a long caption wraps under it.
      h << "<figure style='width:" << im.rgb.cols << "px'><img src='data:image/png;base64," << base64(png)
        << "'/><figcaption>" << esc(im.caption) << "</figcaption></figure>";
    };
    // A composite and its error image ("NAME (defaults), ..." then "NAME: ...") stay side by side.
    for (size_t i = 0; i < images.size(); ++i) {
      const std::string& c = images[i].caption;
      const std::string name = c.substr(0, c.find(" ("));
      const bool pair = i + 1 < images.size() && images[i + 1].caption.rfind(name + ":", 0) == 0;
      h << "<div style='display:inline-block;white-space:nowrap;vertical-align:top;margin-right:12px'>";
      figure(images[i]);
      if (pair) figure(images[++i]);
      h << "</div>";
    }
  }
  h << "</body></html>\n";
  capture::writeFileAtomically(path, h.str());
}

}  // namespace mrgi::evaluation
