// The predicted-FRF CSV contract (DESIGN.md) and the validation metrics mu_acc (Eq. 70-71) and
// error reduction (Eq. 72).
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "model/frf_csv.hpp"
#include "model/frf_metrics.hpp"

namespace fm = feedloop::model;
using fm::Complex;

namespace {

std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("feedloop_model_" + std::to_string(::getpid()) + "_" + name))
      .string();
}

fm::DeltaLpvModel table1_model(fm::ForceTransform f = fm::ForceTransform::Paper) {
  auto m = fm::DeltaLpvModel::create(fm::DeltaParams{}, f);
  EXPECT_TRUE(m.ok());
  return *m;
}

}  // namespace

TEST(FrfCsv, DefaultGridIs247Points) {
  const fm::FrequencyGrid g;
  EXPECT_EQ(g.size(), 247);
  EXPECT_DOUBLE_EQ(g.at_hz(0), 2.0);
  EXPECT_DOUBLE_EQ(g.at_hz(246), 125.0);
}

TEST(FrfCsv, WritesContractAndReadsBack) {
  const auto model = table1_model();
  const std::string path = temp_path("frf.csv");
  ASSERT_TRUE(fm::write_frf_csv(path, model, Eigen::Vector3d(40, -69, 30)).ok());
  std::ifstream in(path);
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header.substr(0, 40), "freq_hz,A_A_re,A_A_im,A_B_re,A_B_im,A_C_");
  EXPECT_NE(header.find("C_C_re,C_C_im"), std::string::npos);
  auto back = fm::read_frf_csv(path);
  ASSERT_TRUE(back.ok()) << back.error().to_string();
  ASSERT_EQ(back->size(), 247);
  auto op = model.at({40, -69, 30});
  ASSERT_TRUE(op.ok());
  for (int k : {0, 100, 246}) {
    const Eigen::Matrix3cd h = model.frf_hz(*op, back->freq_hz[static_cast<size_t>(k)]);
    EXPECT_LT((back->h[static_cast<size_t>(k)] - h).cwiseAbs().maxCoeff(), 1e-10 * h.cwiseAbs().maxCoeff());
  }
  std::filesystem::remove(path);
}

TEST(FrfCsv, PassesTheSharedContractChecker) {
  const std::string checker = std::string(FEEDLOOP_SHARED_DIR) + "/tools/check_contracts.py";
  if (!std::filesystem::exists(checker)) GTEST_SKIP() << "contract checker not found at " << checker;
  if (std::system("python3 -c 'import csv' >/dev/null 2>&1") != 0) GTEST_SKIP() << "python3 is missing";
  for (auto form : {fm::ForceTransform::Paper, fm::ForceTransform::VirtualWork}) {
    const std::string path = temp_path(std::string("check_") + fm::to_string(form) + ".csv");
    ASSERT_TRUE(fm::write_frf_csv(path, table1_model(form), Eigen::Vector3d(-80, 0, 30)).ok());
    const std::string cmd = "python3 '" + checker + "' frf '" + path + "' > '" + path + ".out' 2>&1";
    const int rc = std::system(cmd.c_str());
    std::ifstream out(path + ".out");
    const std::string text((std::istreambuf_iterator<char>(out)), std::istreambuf_iterator<char>());
    EXPECT_EQ(rc, 0) << text;
    std::filesystem::remove(path);
    std::filesystem::remove(path + ".out");
  }
}

TEST(FrfCsv, ReaderReportsWhereItFails) {
  const std::string path = temp_path("bad.csv");
  {
    std::ofstream out(path);
    out << "# comment\nfreq_hz";
    for (char i : {'A', 'B', 'C'})
      for (char j : {'A', 'B', 'C'}) out << ',' << i << '_' << j << "_re," << i << '_' << j << "_im";
    out << "\n2";
    for (int k = 0; k < 18; ++k) out << ",1";
    out << "\n2.5,1,x\n";
  }
  auto r = fm::read_frf_csv(path);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().where.line, 4);
  EXPECT_EQ(r.error().where.column, 3);
  EXPECT_FALSE(fm::read_frf_csv(path + ".missing").ok());
  std::filesystem::remove(path);
}

TEST(FrfCsv, UnreachablePositionIsAnError) {
  const auto st = fm::write_frf_csv(temp_path("never.csv"), table1_model(), Eigen::Vector3d(0, 300, 30));
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().message.find("out of reach"), std::string::npos);
}

TEST(FrfMetrics, IdenticalFrfsGive100Percent) {
  auto set = table1_model().frf(Eigen::Vector3d(0, 0, 30), fm::FrequencyGrid{});
  ASSERT_TRUE(set.ok());
  for (auto q : {fm::FrfQuantity::Magnitude, fm::FrfQuantity::Phase, fm::FrfQuantity::ComplexValue}) {
    auto acc = fm::mu_acc(*set, *set, q);
    ASSERT_TRUE(acc.ok());
    EXPECT_LT((acc->array() - 100.0).abs().maxCoeff(), 1e-12) << fm::to_string(q);
  }
}

TEST(FrfMetrics, PerturbedFrfsLoseAccuracyByTheRightAmount) {
  auto set = table1_model().frf(Eigen::Vector3d(0, 0, 30), fm::FrequencyGrid{});
  ASSERT_TRUE(set.ok());
  const auto m = set->entry(0, 0);
  // 10 % larger everywhere: magnitude and complex errors are exactly 10 %.
  std::vector<Complex> p(m.size());
  for (size_t k = 0; k < m.size(); ++k) p[k] = 1.1 * m[k];
  EXPECT_NEAR(*fm::mu_acc(m, p, fm::FrfQuantity::Magnitude), 90.0, 1e-9);
  EXPECT_NEAR(*fm::mu_acc(m, p, fm::FrfQuantity::ComplexValue), 90.0, 1e-9);
  EXPECT_NEAR(*fm::mu_acc(m, p, fm::FrfQuantity::Phase), 100.0, 1e-9);
  // A 5 degree phase lag everywhere: the phase error is 5 deg / |phase| at each point.
  const Complex rot = std::polar(1.0, -5.0 * std::numbers::pi / 180.0);
  for (size_t k = 0; k < m.size(); ++k) p[k] = rot * m[k];
  auto ph = fm::mu_acc(m, p, fm::FrfQuantity::Phase);
  ASSERT_TRUE(ph.ok());
  EXPECT_LT(*ph, 99.0);
  EXPECT_NEAR(*fm::mu_acc(m, p, fm::FrfQuantity::Magnitude), 100.0, 1e-9);
  // Position dependence seen by the metric: centre model vs the prediction at (-80, 0).
  auto far = table1_model().frf(Eigen::Vector3d(-80, 0, 30), fm::FrequencyGrid{});
  ASSERT_TRUE(far.ok());
  auto acc = fm::mu_acc(*far, *set, fm::FrfQuantity::Magnitude);
  ASSERT_TRUE(acc.ok());
  EXPECT_LT((*acc)(0, 0), 99.0);
}

TEST(FrfMetrics, ErrorReductionEq72) {
  std::vector<Complex> m{{1, 0}, {2, 0}, {4, 0}};
  std::vector<Complex> base{{1.2, 0}, {2.4, 0}, {4.8, 0}};  // 20 % error
  std::vector<Complex> pred{{1.05, 0}, {2.1, 0}, {4.2, 0}};  // 5 % error
  auto r = fm::error_reduction_pct(m, pred, base, fm::FrfQuantity::Magnitude);
  ASSERT_TRUE(r.ok());
  EXPECT_NEAR(*r, 75.0, 1e-9);
  // A prediction worse than the baseline gives a negative reduction (as in Table III).
  auto worse = fm::error_reduction_pct(m, base, pred, fm::FrfQuantity::Magnitude);
  EXPECT_NEAR(*worse, -300.0, 1e-9);
  EXPECT_FALSE(fm::error_reduction_pct(m, pred, m, fm::FrfQuantity::Magnitude).ok());
  EXPECT_FALSE(fm::mu_acc(m, std::vector<Complex>{{1, 0}}, fm::FrfQuantity::Magnitude).ok());
}

TEST(FrfCsv, InvalidGridsHaveNoPoints) {
  EXPECT_EQ((fm::FrequencyGrid{5.0, 1.0, 0.5}).size(), 0);
  EXPECT_EQ((fm::FrequencyGrid{1.0, 5.0, 0.0}).size(), 0);
  EXPECT_EQ((fm::FrequencyGrid{1.0, 1e300, 1e-300}).size(), 0);
  EXPECT_FALSE((fm::FrequencyGrid{1.0, 5.0, -1.0}).validate().ok());
  EXPECT_EQ((fm::FrequencyGrid{1.0, 5.0, 2.0}).size(), 3);
  EXPECT_TRUE((fm::FrequencyGrid{1.0, 5.0, 2.0}).validate().ok());
}
