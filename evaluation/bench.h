#pragma once
// mrgi bench: the speed/accuracy sweep of the lighting techniques against the path-traced reference, its
// report (CSV, self-contained HTML with SVG plots) and the presets chosen from the measured front.
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "lighting/scene_file.h"

namespace mrgi::evaluation {

/// One configuration of the sweep: the techniques by role and every knob; `varied` names the knob this
/// configuration moves away from the defaults ("group.knob"; "" = the defaults themselves), which the
/// scaling plots group by.
struct BenchConfig {
  lighting::TechniqueChoice technique;
  lighting::KnobSet knobs;
  std::string varied;
};

/// The knobs the configuration's techniques use, as JSON by group (the record's "knobs").
nlohmann::json knobsJson(const BenchConfig& c);

/// From the registry: for each technique (all when `technique` is empty, else the techniques of that
/// spelling) its defaults and one-knob-at-a-time sweeps over the declared sweep values of the shared frame
/// knobs and its own; each alias and each pairing of a real-pixel technique with another virtual-object
/// technique at the defaults. quick: the declared quick values only (tests, small sessions).
std::vector<BenchConfig> sweepConfigs(const std::string& technique, bool quick, const lighting::KnobSet& base);

/// The knob moves that cost a technique nothing, made together: for each technique's defaults (configs[i]
/// measured as records[i]), its one-knob moves that took at least 10 % off the lighting time (more than the timing
/// noise) and kept the error (mean of rel_error_delta and rel_error_virtual) within 1 % of the defaults' — the fastest
/// value per knob — all applied at once, as one configuration with varied = "combined" (none for a technique with fewer
/// than two such moves); and the technique's most accurate one-knob row, when at least 5 % more accurate than its
/// defaults, with the free moves of its other knobs ("combined accurate"; none without such a row or move). Measured
/// like the others, they join the front the presets are chosen from: the one-at-a-time sweep cannot see that
/// savings add up, nor what accuracy costs once they are taken.
std::vector<BenchConfig> combinedConfigs(const std::vector<BenchConfig>& configs, const nlohmann::json& records);

/// Presets from the measured records: the Pareto front of (ms_replay — ms_lighting in a record without it —, error)
/// where error is the mean of rel_error_delta and rel_error_virtual; accurate = least error, fast = the fastest
/// front point within twice the least error, balanced = among the front points at least 5 % more accurate than
/// fast, the one with the least (ms / ms_min) x (error / error_min) (fast when there is none).
/// Returns {"fast": record, "balanced": record, "accurate": record} (empty object without records).
nlohmann::json choosePresets(const nlohmann::json& records);

/// Whether neighbouring presets (fast / balanced, balanced / accurate) are told apart by the real-pixel delta
/// error measured without the reference's noise: per session where both records hold
/// rel_rms_delta_unbiased, their 95 % intervals; "resolved" only when no session's intervals overlap.
/// {"fast_vs_balanced": {"resolved": bool, "sessions": [{"session", "a": [v, lo, hi], "b": [...]}]}, ...};
/// a pair of the same record, or without intervals, is left out.
nlohmann::json presetDifferences(const nlohmann::json& presets);

/// Images the HTML report shows, PNG-encoded.
struct ReportImage {
  std::string caption;
  cv::Mat rgb;  ///< RGB8
};

/// A gallery row: one technique's composite (RGB8) and shading result (RGBA32F: real-pixel delta, a = virtual)
/// of a frame that has a reference.
struct GalleryRow {
  std::string label;
  cv::Mat composite, shade;
};
/// The crop around the objects that a gallery shows: the reference's virtual pixels' bounding box grown by
/// `grow` times its size on every side, within the image (the whole image when the frame shows no object).
cv::Rect galleryCrop(const cv::Mat& virtualMask, double grow = 1.0);
/// One PNG-ready image (RGB8): a labelled cell for the reference and one per technique in a grid of three
/// columns, each the crop of the composite beside the crop of the real-pixel delta (mid grey = no change,
/// black = the reference's darkest change or more, white as bright the other way, on a square-root scale so
/// that a shadow's faint wide part shows; the objects' own pixels blue); tiles at least 160 pixels high.
cv::Mat galleryImage(const std::string& title, const cv::Mat& referenceComposite, const cv::Mat& referenceDelta,
                     const cv::Mat& virtualMask, const std::vector<GalleryRow>& rows);

/// The first line of the CSV writeCsv writes (its column names), and the columns every version's began with (by
/// which an earlier version's file is known as the bench's own).
extern const char* const kCsvHeader;
extern const char* const kCsvSignature;
void writeCsv(const std::string& path, const nlohmann::json& records);
/// doc: the bench's JSON document (records, presets, reference, renderer).
void writeHtml(const std::string& path, const nlohmann::json& doc, const std::vector<ReportImage>& images);

}  // namespace mrgi::evaluation
