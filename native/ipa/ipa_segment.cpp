// roomseg-bench's driver for ipa_room_segmentation (ipa320/ipa_coverage_planning): one map in,
// one label image out, with one of the authors' five algorithms called as their ROS action
// server calls it (ros/src/room_segmentation_server.cpp), without ROS.
//
//   ipa_segment --map MAP.png --resolution M_PER_PX --algorithm NAME --models DIR --work DIR
//               --out LABELS.png [--param KEY=VALUE ...]
//
// MAP.png: 8-bit grey, 255 = free, anything else = occupied (the server's MONO8 input map).
// NAME: morphological | distance | voronoi | semantic | vrf.
// DIR (--models): the package's trained classifiers (ipa_room_segmentation/common/files/classifier_models/).
// --work: a folder of the caller's where the algorithms keep their copy of the classifiers.
// LABELS.png: 16-bit grey, 0 = no room (obstacle or free space no room took), 1..N = rooms
// (numbered in row-major order of their first pixel).
// KEY=VALUE: the parameters of the authors' params YAML (room_area_factor_lower_limit, ...).
// --verbose 1: the algorithms' own progress lines (std::cout) go to stderr; otherwise they are dropped.
// Exit 0 and "rooms N" on stdout; otherwise one line on stderr and exit 2 (bad input) or 1.
#include <opencv2/opencv.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <ipa_room_segmentation/morphological_segmentation.h>
#include <ipa_room_segmentation/distance_segmentation.h>
#include <ipa_room_segmentation/voronoi_segmentation.h>
#include <ipa_room_segmentation/adaboost_classifier.h>
#ifdef ROOMSEG_IPA_WITH_VRF
#include <ipa_room_segmentation/voronoi_random_field_segmentation.h>
#endif
#include <cstdlib>
#include <exception>
#include <iostream>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>

namespace {

struct BadInput : std::runtime_error { using std::runtime_error::runtime_error; };

// The authors' defaults: ros/launch/room_segmentation_action_server_params.yaml (areas in m²).
std::map<std::string, double> defaults(const std::string& algorithm) {
  if (algorithm == "morphological")
    return {{"room_area_factor_lower_limit", 0.8}, {"room_area_factor_upper_limit", 47.0}};
  if (algorithm == "distance")
    return {{"room_area_factor_lower_limit", 0.35}, {"room_area_factor_upper_limit", 163.0}};
  if (algorithm == "voronoi")
    return {{"room_area_factor_lower_limit", 0.1}, {"room_area_factor_upper_limit", 1000000.0},
            {"voronoi_neighborhood_index", 280}, {"max_iterations", 150},
            {"min_critical_point_distance_factor", 0.5}, {"max_area_for_merging", 12.5}};
  if (algorithm == "semantic")
    return {{"room_area_factor_lower_limit", 1.0}, {"room_area_factor_upper_limit", 1000000.0}};
  if (algorithm == "vrf")
    return {{"room_area_lower_limit", 1.53}, {"room_area_upper_limit", 1000000.0},
            {"voronoi_random_field_epsilon_for_neighborhood", 5}, {"max_iterations", 150},
            {"min_neighborhood_size", 4}, {"min_voronoi_random_field_node_distance", 7.0},
            {"max_voronoi_random_field_inference_iterations", 9000}, {"max_area_for_merging", 12.5}};
  throw BadInput("--algorithm " + algorithm + ": expected morphological, distance, voronoi, semantic or vrf");
}

double number(const std::string& what, const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(v))
    throw BadInput(what + "=" + text + ": expected a number");
  return v;
}

int integer(const std::map<std::string, double>& p, const std::string& key) {
  const double v = p.at(key);
  if (v != static_cast<int>(v) || v < 0)
    throw BadInput("--param " + key + "=" + std::to_string(v) + ": expected a whole number >= 0");
  return static_cast<int>(v);
}

std::string slash(std::string dir) { return (dir.empty() || dir.back() == '/') ? dir : dir + "/"; }

int run(int argc, char** argv) {
  std::map<std::string, std::string> opt;
  std::map<std::string, std::string> params;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      std::printf("usage: ipa_segment --map MAP.png --resolution M_PER_PX --algorithm "
                  "morphological|distance|voronoi|semantic|vrf --models DIR --work DIR --out LABELS.png "
                  "[--param KEY=VALUE ...]\n");
      return 0;
    }
    if (a.rfind("--", 0) != 0 || i + 1 >= argc) throw BadInput("argument " + a + ": expected --name value (see --help)");
    const std::string v = argv[++i];
    if (a == "--param") {
      const size_t eq = v.find('=');
      if (eq == std::string::npos) throw BadInput("--param " + v + ": expected KEY=VALUE");
      params[v.substr(0, eq)] = v.substr(eq + 1);
    } else {
      opt[a.substr(2)] = v;
    }
  }
  for (const char* need : {"map", "resolution", "algorithm", "models", "work", "out"})
    if (!opt.count(need)) throw BadInput(std::string("--") + need + ": missing (see --help)");
  for (const auto& kv : opt)
    if (kv.first != "map" && kv.first != "resolution" && kv.first != "algorithm" && kv.first != "models" &&
        kv.first != "work" && kv.first != "out" && kv.first != "verbose")
      throw BadInput("--" + kv.first + ": unknown option (see --help)");

  const std::string algorithm = opt["algorithm"];
  std::map<std::string, double> p = defaults(algorithm);
  for (const auto& kv : params) {
    if (!p.count(kv.first)) {
      std::string keys;
      for (const auto& d : p) keys += (keys.empty() ? "" : ", ") + d.first;
      throw BadInput("--param " + kv.first + ": not a parameter of " + algorithm + " (expected one of " + keys + ")");
    }
    p[kv.first] = number("--param " + kv.first, kv.second);
  }
  const double resolution = number("--resolution", opt["resolution"]);
  if (!(resolution > 0)) throw BadInput("--resolution " + opt["resolution"] + ": expected metres per pixel > 0");

  cv::Mat map = cv::imread(opt["map"], cv::IMREAD_UNCHANGED);
  if (map.empty()) throw BadInput("--map " + opt["map"] + ": not a readable image");
  if (map.type() != CV_8UC1) throw BadInput("--map " + opt["map"] + ": expected an 8-bit single-channel image");
  if (map.rows < 3 || map.cols < 3) throw BadInput("--map " + opt["map"] + ": expected at least 3 x 3 pixels");
  if (cv::countNonZero(map == 255) == 0) throw BadInput("--map " + opt["map"] + ": no free (255) pixel");
  cv::Mat input = cv::Mat::zeros(map.size(), CV_8UC1);
  input.setTo(255, map == 255);  // the server's map: free 255, the rest occupied 0

  const std::string models = slash(opt["models"]);
  const std::string work = slash(opt["work"]);
  cv::Mat segmented;
  if (algorithm == "morphological") {
    MorphologicalSegmentation s;
    s.segmentMap(input, segmented, resolution, p["room_area_factor_lower_limit"], p["room_area_factor_upper_limit"]);
  } else if (algorithm == "distance") {
    DistanceSegmentation s;
    s.segmentMap(input, segmented, resolution, p["room_area_factor_lower_limit"], p["room_area_factor_upper_limit"]);
  } else if (algorithm == "voronoi") {
    VoronoiSegmentation s;
    s.segmentMap(input, segmented, resolution, p["room_area_factor_lower_limit"], p["room_area_factor_upper_limit"],
                 integer(p, "voronoi_neighborhood_index"), integer(p, "max_iterations"),
                 p["min_critical_point_distance_factor"], p["max_area_for_merging"], false);
  } else if (algorithm == "semantic") {
    AdaboostClassifier s;
    s.segmentMap(input, segmented, resolution, p["room_area_factor_lower_limit"], p["room_area_factor_upper_limit"],
                 work, models, false);
  } else {
#ifdef ROOMSEG_IPA_WITH_VRF
    VoronoiRandomFieldSegmentation s;
    std::vector<uint> labels = {77, 115, 179};  // room, hallway, doorway (the server's)
    std::vector<cv::Point> doors;
    s.segmentMap(input, segmented, integer(p, "voronoi_random_field_epsilon_for_neighborhood"),
                 integer(p, "max_iterations"), integer(p, "min_neighborhood_size"), labels,
                 p["min_voronoi_random_field_node_distance"], false, work, models,
                 integer(p, "max_voronoi_random_field_inference_iterations"), resolution,
                 p["room_area_lower_limit"], p["room_area_upper_limit"], p["max_area_for_merging"], &doors);
#else
    throw std::runtime_error("--algorithm vrf: this ipa_segment was built without OpenGM (make ipa-env OPENGM_SRC=...)");
#endif
  }
  if (segmented.empty() || segmented.type() != CV_32SC1 || segmented.size() != input.size())
    throw std::runtime_error(algorithm + " returned no label image of the map's size");

  // rooms: labels in (0, 65280) as the server counts them; renumbered 1..N in row-major order
  std::map<int, int> index;
  cv::Mat out = cv::Mat::zeros(segmented.size(), CV_16UC1);
  for (int r = 0; r < segmented.rows; ++r)
    for (int c = 0; c < segmented.cols; ++c) {
      const int label = segmented.at<int>(r, c);
      if (label <= 0 || label >= 65280) continue;
      auto it = index.find(label);
      if (it == index.end()) {
        if (index.size() >= 65535) throw std::runtime_error("more than 65535 rooms");
        it = index.emplace(label, static_cast<int>(index.size()) + 1).first;
      }
      out.at<unsigned short>(r, c) = static_cast<unsigned short>(it->second);
    }
  if (!cv::imwrite(opt["out"], out)) throw BadInput("--out " + opt["out"] + ": could not write the label image");
  std::printf("rooms %zu\n", index.size());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  // the algorithms report progress on std::cout; the driver's own answer is its last stdout line
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);  // our one line says what failed
  std::ostringstream chatter;
  bool verbose = false;
  for (int i = 1; i + 1 < argc; ++i)
    if (std::string(argv[i]) == "--verbose") verbose = std::string(argv[i + 1]) != "0";
  std::streambuf* keep = std::cout.rdbuf(verbose ? std::cerr.rdbuf() : chatter.rdbuf());
  int rc;
  try {
    rc = run(argc, argv);
  } catch (const BadInput& e) {
    std::fprintf(stderr, "ipa_segment: %s\n", e.what());
    rc = 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ipa_segment: %s\n", e.what());
    rc = 1;
  } catch (...) {
    std::fprintf(stderr, "ipa_segment: failed (an unknown exception)\n");
    rc = 1;
  }
  std::cout.rdbuf(keep);
  return rc;
}
