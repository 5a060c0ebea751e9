// roomseg-bench: the weak hypotheses of a boosted classifier, as OpenCV 2's
// CvBoost::predict(sample, missing, weak_responses) returned them: one value per weak tree, the
// value of the leaf the sample reaches in that tree (the trees' sum is Boost's PREDICT_SUM).
//
// Why: ipa_room_segmentation's VRF takes these as features (getAdaBoostFeatureVector). Its
// OpenCV >= 3 branch calls cv::ml::Boost::predict(sample, weaker) instead, which writes ONE
// class label into `weaker` (recreated as 1 x 1) and leaves the other number_of_classifiers_ - 1
// values the loop then reads uninitialised: the VRF's answer changes from run to run on the same
// map. `make ipa-env` (IPA_VRF_FIX=1, the default) compiles a copy of the authors'
// voronoi_random_field_segmentation.cpp with those calls routed here; IPA_VRF_FIX=0 compiles it
// as published (docs/baselines.md).
#ifndef ROOMSEG_IPA_WEAK_RESPONSES_H
#define ROOMSEG_IPA_WEAK_RESPONSES_H
#include <opencv2/core.hpp>
#include <opencv2/ml.hpp>
#include <stdexcept>
#include <string>
#include <vector>

inline void roomseg_weak_responses(const cv::Ptr<cv::ml::Boost>& boost, const cv::Mat& sample, cv::Mat& weak) {
  if (boost.empty() || sample.type() != CV_32FC1 || sample.rows != 1)
    throw std::runtime_error("weak responses: expected a loaded classifier and one CV_32F sample row");
  const std::vector<int>& roots = boost->getRoots();
  const std::vector<cv::ml::DTrees::Node>& nodes = boost->getNodes();
  const std::vector<cv::ml::DTrees::Split>& splits = boost->getSplits();
  if (weak.rows != 1 || weak.cols != static_cast<int>(roots.size()) || weak.type() != CV_32FC1)
    throw std::runtime_error("weak responses: the classifier has " + std::to_string(roots.size()) +
                             " weak trees, the caller expects " + std::to_string(weak.cols));
  for (size_t t = 0; t < roots.size(); ++t) {
    int n = roots[t];
    // as cv::ml::DTrees' prediction walks an ordered split; the authors' models have ordered
    // features only (cat_var_count 0), so no categorical split is handled here
    while (nodes[n].split >= 0) {
      const cv::ml::DTrees::Split& s = splits[nodes[n].split];
      if (s.varIdx < 0 || s.varIdx >= sample.cols)
        throw std::runtime_error("weak responses: a split on feature " + std::to_string(s.varIdx) + " of " +
                                 std::to_string(sample.cols));
      n = sample.at<float>(0, s.varIdx) <= s.c ? nodes[n].left : nodes[n].right;
    }
    weak.at<float>(0, static_cast<int>(t)) = static_cast<float>(nodes[n].value);
  }
}
#endif
