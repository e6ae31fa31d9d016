// Temporal line matching on constructed segments and descriptors: flow-consistency outlier rejection and the guided
// pass (looser descriptor bound under the fitted flow).
#include <gtest/gtest.h>

#include <random>

#include "linnet/core/error.h"
#include "linnet/features/line_matching.h"

namespace linnet {
namespace {

LbdDescriptor randomDescriptor(std::mt19937_64* rng) {
  return LbdDescriptor{(*rng)(), (*rng)(), (*rng)(), (*rng)()};
}

// Flips `bits` distinct bits of d.
LbdDescriptor flipBits(LbdDescriptor d, int bits, std::mt19937* rng) {
  std::vector<int> idx(256);
  for (int k = 0; k < 256; ++k) idx[k] = k;
  std::shuffle(idx.begin(), idx.end(), *rng);
  for (int k = 0; k < bits; ++k) d[idx[k] / 64] ^= std::uint64_t{1} << (idx[k] % 64);
  return d;
}

struct Scenario {
  std::vector<LineSegment> prev, cur;
  std::vector<LbdDescriptor> prev_desc, cur_desc;
};

// 16 segments on a 4 x 4 grid (150 px apart, far beyond the shift gate), moved by a small similarity flow.
// Segment 13: good descriptor, 20 px off the flow (an outlier). Segment 14: 100 bits changed, on the flow.
// Segment 15: 100 bits changed and 8 px off the flow.
Scenario makeScenario() {
  Scenario s;
  std::mt19937_64 rng64(5);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> angle(0.0, 3.14159);
  const Vec2 centre(375.5, 239.5);
  const double c = std::cos(0.01), sn = std::sin(0.01), scale = 1.01;
  for (int k = 0; k < 16; ++k) {
    const Vec2 m(80.0 + 150.0 * (k % 4), 40.0 + 120.0 * (k / 4));
    const double a = angle(rng);
    const Vec2 d(std::cos(a), std::sin(a));
    LineSegment p{m - 30.0 * d, m + 30.0 * d};
    auto flow = [&](const Vec2& x) -> Vec2 {
      const Vec2 r = x - centre;
      return centre + scale * Vec2(c * r.x() - sn * r.y(), sn * r.x() + c * r.y()) + Vec2(6.0, -4.0);
    };
    LineSegment q{flow(p.s), flow(p.e)};
    const Vec2 off = (k == 13 ? 20.0 : k == 15 ? 8.0 : 0.0) * q.normal();
    q.s += off;
    q.e += off;
    s.prev.push_back(p);
    s.cur.push_back(q);
    s.prev_desc.push_back(randomDescriptor(&rng64));
    s.cur_desc.push_back(flipBits(s.prev_desc.back(), k >= 14 ? 100 : 12, &rng));
  }
  return s;
}

TEST(LineMatching, TemporalRejectsFlowOutliersAndGuidedPassRecoversChangedDescriptors) {
  const Scenario s = makeScenario();
  const Vec2 centre(375.5, 239.5);
  TemporalMatchOptions opt;
  opt.guided_max_hamming = 0;
  std::vector<int> m;
  const int plain = matchTemporal(opt, s.prev, s.prev_desc, s.cur, s.cur_desc, centre, &m);
  for (int k = 0; k < 13; ++k) EXPECT_EQ(m[k], k) << k;
  EXPECT_EQ(m[13], -1);  // off the flow
  EXPECT_EQ(m[14], -1);  // descriptor beyond max_hamming
  EXPECT_EQ(m[15], -1);
  EXPECT_EQ(plain, 13);

  opt.guided_max_hamming = 120;
  const int guided = matchTemporal(opt, s.prev, s.prev_desc, s.cur, s.cur_desc, centre, &m);
  for (int k = 0; k < 13; ++k) EXPECT_EQ(m[k], k) << k;
  EXPECT_EQ(m[13], -1);  // its descriptor is fine, but it stays off the flow
  EXPECT_EQ(m[14], 14);  // recovered: on the flow, within the looser bound
  EXPECT_EQ(m[15], -1);  // off the flow by more than guided_px
  EXPECT_EQ(guided, 14);

  opt.guided_max_hamming = 90;  // bound below its 100 bits
  matchTemporal(opt, s.prev, s.prev_desc, s.cur, s.cur_desc, centre, &m);
  EXPECT_EQ(m[14], -1);
}

TEST(LineMatching, NeighbourFlowFitsTheDonorsNormalComponents) {
  // Donors of several directions moving with one flow f, their measured flows carrying noise along themselves (the
  // unobserved part): the fit recovers f from the normal components alone. Far donors beyond `count` do not count.
  const Vec2 f(-35.0, 12.0);
  std::vector<LineSegment> segs;
  std::vector<Vec2> flows;
  for (int k = 0; k < 6; ++k) {
    const double a = 0.5 * k;
    const Vec2 mid(300.0 + 20.0 * k, 200.0 - 10.0 * k), u(std::cos(a), std::sin(a));
    segs.push_back({mid - 30.0 * u, mid + 30.0 * u});
    flows.push_back(f + (k % 2 ? 40.0 : -25.0) * u);  // along-line noise
  }
  segs.push_back({Vec2(700.0, 450.0), Vec2(740.0, 460.0)});  // far away, moving otherwise
  flows.push_back(Vec2(500.0, -500.0));
  const LineSegment target{Vec2(330.0, 150.0), Vec2(360.0, 190.0)};
  const Vec2 got = neighbourFlow(target, segs, flows, 6);
  // The ridge (0.05 of one donor) pulls the fit towards zero by a few per cent at most.
  EXPECT_NEAR(got.x(), f.x(), 0.03 * f.norm());
  EXPECT_NEAR(got.y(), f.y(), 0.03 * f.norm());
  // With the far donor among the neighbours, the fit moves.
  EXPECT_GT((neighbourFlow(target, segs, flows, 7) - f).norm(), 10.0);

  // Parallel donors (horizontal) tell only the vertical flow: the horizontal part stays at zero.
  std::vector<LineSegment> par;
  std::vector<Vec2> par_flows;
  for (int k = 0; k < 4; ++k) {
    par.push_back({Vec2(100.0, 100.0 + 30.0 * k), Vec2(200.0, 100.0 + 30.0 * k)});
    par_flows.push_back(Vec2(80.0 + 10.0 * k, -20.0));
  }
  const Vec2 p = neighbourFlow(target, par, par_flows, 6);
  EXPECT_NEAR(p.x(), 0.0, 1e-9);
  EXPECT_NEAR(p.y(), -20.0 * 4.0 / 4.05, 1e-9);

  EXPECT_EQ(neighbourFlow(target, {}, {}, 6), Vec2::Zero());
  EXPECT_EQ(neighbourFlow(target, segs, flows, 0), Vec2::Zero());
  EXPECT_THROW(neighbourFlow(target, segs, {Vec2::Zero()}, 6), UsageError);
}

}  // namespace
}  // namespace linnet
