// The contact-law unit (backlash_law.h): its tables (regions, coefficients, switching surfaces,
// tie-breaks, watched surfaces) against the law evaluated directly, and the Model assembling its
// tables from them.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "millkit/driveline/backlash_law.h"
#include "millkit/driveline/model.h"
#include "scene_builder.h"

using namespace millkit::driveline;

namespace {

constexpr ContactLaw kLaws[] = {ContactLaw::kLimited, ContactLaw::kNoPull, ContactLaw::kLinear};
constexpr double kEpsilon = std::numeric_limits<double>::epsilon();
// The table and the direct evaluation round the same few terms in another order.
constexpr double kRoundoffUlps = 16.0;

struct LinkPoint {
  double c, d, b, psi, v;
};

std::array<double, kLinkSurfaceCount> SurfaceValues(const LinkPoint& p) {
  const auto rows = LinkSurfaceRows(p.c, p.d, p.b);
  std::array<double, kLinkSurfaceCount> g{};
  for (int s = 0; s < kLinkSurfaceCount; ++s)
    g[s] = rows[s].kpsi * p.psi + rows[s].kv * p.v + rows[s].k0;
  return g;
}

// Sides from the signs; a surface value of exactly zero takes the default side.
std::array<int, kLinkSurfaceCount> Sides(const LinkPoint& p) {
  const auto g = SurfaceValues(p);
  std::array<int, kLinkSurfaceCount> side{};
  for (int s = 0; s < kLinkSurfaceCount; ++s) {
    side[s] = g[s] > 0.0 ? 1 : g[s] < 0.0 ? -1 : kLinkDefaultSides[s];
  }
  return side;
}

LinkPhase RegionAt(ContactLaw law, const LinkPoint& p) {
  return PhaseFromSides(law, Sides(p).data());
}

double TableTorque(ContactLaw law, const LinkPoint& p) {
  const LinkTorqueCoefficients k = CoefficientsOf(RegionAt(law, p), p.c, p.d, p.b);
  return k.kpsi * p.psi + k.kv * p.v + k.k0;
}

bool Watches(const WatchedLinkSurfaces& watched, int surface, int side) {
  return std::any_of(watched.begin(), watched.end(), [&](const LinkSurfaceSide& w) {
    return w.surface == surface && w.side == side;
  });
}

// Random links and points: everywhere, and on and near each switching surface (exactly on S0 and
// S1, within roundoff of S2..S5, and 1e-12 … 1e-1 relative to either side), the corners included.
class PointSource {
 public:
  explicit PointSource(unsigned seed) : random_(seed) {}

  double LogUniform(double lo, double hi) {
    return std::exp(std::uniform_real_distribution<double>(std::log(lo), std::log(hi))(random_));
  }
  double Sign() { return std::bernoulli_distribution(0.5)(random_) ? 1.0 : -1.0; }
  int Pick(int n) { return std::uniform_int_distribution<int>(0, n - 1)(random_); }

  LinkPoint Next() {
    LinkPoint p;
    p.c = LogUniform(1e-2, 1e10);
    p.d = Pick(10) == 0 ? 0.0 : LogUniform(1e-4, 1e7);
    p.b = Pick(20) == 0 ? 0.0 : LogUniform(1e-9, 1e-1);
    const double half = 0.5 * p.b;
    const double twist = std::max(half, 1e-9);
    // Speeds of the size that makes d ψ' comparable to c (ψ ∓ b/2), and of any other size.
    const double v_scale = p.d > 0.0 ? p.c * twist / p.d : 1.0;
    p.v = Sign() * v_scale * LogUniform(1e-6, 1e6);
    const double flank = Sign();
    // A twist in contact on `flank`, τc = c (ψ ∓ b/2).
    const double contact = flank * (half + twist * LogUniform(1e-6, 1e2));
    const double tau_c = p.c * (contact - flank * half);
    const double nudge = Sign() * LogUniform(1e-12, 1e-1);
    switch (Pick(8)) {
      case 0:  // anywhere
        p.psi = Sign() * twist * LogUniform(1e-6, 1e2);
        break;
      case 1:  // on S0 or S1 exactly, or one ulp off
        p.psi = flank * half;
        if (Pick(2) == 0) p.psi = std::nextafter(p.psi, Sign() * 1.0);
        break;
      case 2:  // near S0 or S1
        p.psi = flank * half * (1.0 + nudge);
        break;
      case 3:  // on S2 / S4: τc + d ψ' = 0
        p.psi = contact;
        if (p.d > 0.0) p.v = -tau_c / p.d;
        break;
      case 4:  // on S3 / S5: d ψ' = τc
        p.psi = contact;
        if (p.d > 0.0) p.v = tau_c / p.d;
        break;
      case 5:  // near S2 / S4
        p.psi = contact;
        if (p.d > 0.0) p.v = -tau_c / p.d * (1.0 + nudge);
        break;
      case 6:  // near S3 / S5
        p.psi = contact;
        if (p.d > 0.0) p.v = tau_c / p.d * (1.0 + nudge);
        break;
      default:  // at or near the corner ψ = ±b/2, ψ' = 0 where S0 (S1) meets S2..S5
        p.psi = flank * half * (1.0 + (Pick(2) == 0 ? 0.0 : nudge));
        p.v = Pick(2) == 0 ? 0.0 : p.v * 1e-9;
        break;
    }
    return p;
  }

 private:
  std::mt19937 random_;
};

constexpr int kPoints = 200000;

}  // namespace

TEST_CASE("The law evaluated directly equals the torque from the unit's tables", "[contact_law]") {
  for (ContactLaw law : kLaws) {
    INFO("law " << ContactLawName(law));
    PointSource source(17);
    std::vector<int> hits(7, 0);
    for (int i = 0; i < kPoints; ++i) {
      const LinkPoint p = source.Next();
      const double direct = BacklashTorque(law, p.c, p.d, p.b, p.psi, p.v);
      const double table = TableTorque(law, p);
      const double size = std::abs(p.c * p.psi) + std::abs(p.c * p.b) + std::abs(p.d * p.v);
      INFO("c " << p.c << " d " << p.d << " b " << p.b << " psi " << p.psi << " v " << p.v
                << " region " << LinkPhaseName(RegionAt(law, p)));
      if (std::abs(direct - table) > kRoundoffUlps * kEpsilon * size) {
        CHECK(direct == table);  // fails, printing both
      }
      ++hits[static_cast<int>(RegionAt(law, p))];
    }
    // Every region of the law was visited, and no other.
    for (int r = 0; r < 7; ++r) {
      const auto regions = RegionsOf(law);
      const bool of_law =
          std::find(regions.begin(), regions.end(), static_cast<LinkPhase>(r)) != regions.end();
      INFO("region " << LinkPhaseName(static_cast<LinkPhase>(r)));
      CHECK((hits[r] > 100) == of_law);
    }
  }
}

TEST_CASE("On a switching surface the default sides give the region the law takes there",
          "[contact_law]") {
  // The contact surfaces are exact (ψ ∓ b/2): on them every law still carries no torque, even
  // where the flank's spring-damper piece would not (linear and no_pull pushing: m = d ψ').
  for (ContactLaw law : kLaws) {
    for (double flank : {1.0, -1.0}) {
      const LinkPoint p{1e6, 2e3, 0.02, flank * 0.01, flank * 5.0};
      CHECK(BacklashTorque(law, p.c, p.d, p.b, p.psi, p.v) == 0.0);
      CHECK(RegionAt(law, p) == LinkPhase::kDead);
      CHECK(TableTorque(law, p) == 0.0);
    }
  }
}

// S1 − S0 = b > 0: no link is ever on the contact side of S0 and of S1 at once.
bool Possible(const std::array<int, kLinkSurfaceCount>& side) {
  return !(side[kS0] > 0 && side[kS1] < 0);
}

TEST_CASE("Each region watches exactly the surfaces whose side decides it", "[contact_law]") {
  for (ContactLaw law : kLaws) {
    INFO("law " << ContactLawName(law));
    PointSource source(29);
    for (int i = 0; i < kPoints / 4; ++i) {
      const LinkPoint p = source.Next();
      if (p.b == 0.0) continue;  // S0 and S1 coincide: no link with b = 0 has surfaces
      const auto side = Sides(p);
      const LinkPhase region = PhaseFromSides(law, side.data());
      const WatchedLinkSurfaces watched = WatchedSurfaces(law, region);
      INFO("region " << LinkPhaseName(region));
      for (int s = 0; s < kLinkSurfaceCount; ++s) {
        INFO("surface S" << s);
        auto flipped = side;
        flipped[s] = -side[s];
        if (!Possible(flipped)) continue;
        const bool changes = PhaseFromSides(law, flipped.data()) != region;
        // Watched, on the side the point is on, exactly when going across changes the region.
        CHECK(changes == Watches(watched, s, side[s]));
        CHECK_FALSE(Watches(watched, s, -side[s]));
      }
    }
  }
}

// Watched surfaces that no crossing of that surface alone leaves the region by: limited's
// spring-damper piece meets S0 (S1) only at the corner ψ = ±b/2, ψ' = 0 (there S2 = S3 = d ψ'),
// and its double-spring piece never meets S2 (S4) elsewhere (S2 − S3 = 2 c S0 > 0). The corner,
// where all three are zero, is left through any of them.
bool CornerOnly(ContactLaw law, LinkPhase region, int surface) {
  if (law != ContactLaw::kLimited) return false;
  return (region == LinkPhase::kPosSpringDamper && surface == kS0) ||
         (region == LinkPhase::kNegSpringDamper && surface == kS1) ||
         (region == LinkPhase::kPosDoubleSpring && surface == kS2) ||
         (region == LinkPhase::kNegDoubleSpring && surface == kS4);
}

TEST_CASE("Going across a switching surface changes the region only where both regions watch it",
          "[contact_law]") {
  for (ContactLaw law : kLaws) {
    INFO("law " << ContactLawName(law));
    PointSource source(43);
    std::vector<int> crossings(kLinkSurfaceCount, 0);
    // (region, surface) pairs some crossing left the region through.
    std::vector<std::array<bool, kLinkSurfaceCount>> left(7, std::array<bool, kLinkSurfaceCount>{});
    for (int i = 0; i < kPoints / 4; ++i) {
      LinkPoint p = source.Next();
      if (p.b == 0.0) continue;
      const auto rows = LinkSurfaceRows(p.c, p.d, p.b);
      for (int s = 0; s < kLinkSurfaceCount; ++s) {
        // Step from p along the surface's normal in (ψ, ψ') to either side of it.
        const auto& row = rows[s];
        const double g = row.kpsi * p.psi + row.kv * p.v + row.k0;
        const double n2 = row.kpsi * row.kpsi + row.kv * row.kv;
        const double step = 1e-9 * (std::abs(p.psi) * std::abs(row.kpsi) +
                                    std::abs(p.v) * std::abs(row.kv) + std::abs(row.k0)) +
                            std::abs(g);
        LinkPoint below = p, above = p;
        below.psi = p.psi - (g + step) * row.kpsi / n2;
        below.v = p.v - (g + step) * row.kv / n2;
        above.psi = p.psi - (g - step) * row.kpsi / n2;
        above.v = p.v - (g - step) * row.kv / n2;
        auto side_below = Sides(below), side_above = Sides(above);
        if (side_below[s] != -1 || side_above[s] != 1) continue;  // lost in roundoff
        // Only surface s between them (not at a corner).
        bool only_s = true;
        for (int t = 0; t < kLinkSurfaceCount; ++t) {
          if (t != s && side_below[t] != side_above[t]) only_s = false;
        }
        if (!only_s) continue;
        const LinkPhase from = PhaseFromSides(law, side_below.data());
        const LinkPhase to = PhaseFromSides(law, side_above.data());
        if (from == to) continue;
        ++crossings[s];
        INFO("S" << s << " from " << LinkPhaseName(from) << " to " << LinkPhaseName(to));
        CHECK(Watches(WatchedSurfaces(law, from), s, -1));
        CHECK(Watches(WatchedSurfaces(law, to), s, 1));
        left[static_cast<int>(from)][s] = true;
        left[static_cast<int>(to)][s] = true;
      }
    }
    // Every other watched surface is one the region is left through.
    for (LinkPhase region : RegionsOf(law)) {
      for (const LinkSurfaceSide& w : WatchedSurfaces(law, region)) {
        INFO("region " << LinkPhaseName(region) << " watches S" << w.surface);
        CHECK(left[static_cast<int>(region)][w.surface] == !CornerOnly(law, region, w.surface));
      }
    }
    // S0 and S1 change the region under every law, S2 and S4 under the laws that free a flank,
    // S3 and S5 under the law with a double-spring piece.
    for (int s = 0; s < kLinkSurfaceCount; ++s) {
      INFO("S" << s);
      const bool decides = s <= kS1 || ((s == kS2 || s == kS4) && law != ContactLaw::kLinear) ||
                           law == ContactLaw::kLimited;
      CHECK((crossings[s] > 100) == decides);
    }
  }
}

TEST_CASE("The model assembles its surfaces and watched lists from the unit's per-link answers",
          "[contact_law]") {
  using testing::TwoMassScene;
  for (ContactLaw law : kLaws) {
    INFO("law " << ContactLawName(law));
    Scene scene = TwoMassScene(2.0, 3.0, 1e5, 40.0, 0.01, 0.1, 1e4, law);
    scene.masses.push_back({"c", 1.5});
    scene.links.push_back({"second", 1, 2, 7e4, 25.0, 0.004, -1.0});
    const Model model(scene);
    REQUIRE(model.backlash_link_count() == 2);
    REQUIRE(model.surface_count() == 2 * kLinkSurfaceCount);
    const int one = model.state_size();
    for (int k = 0; k < 2; ++k) {
      const Link& link = model.reduced_scene().links[k];
      const auto rows =
          LinkSurfaceRows(link.stiffness_Nm_per_rad, link.damping_Nms_per_rad, link.backlash_rad);
      const int f = model.FlexibleIndexOf(k);
      const int a = model.SpeedIndex(model.reduction().group_of_mass[link.from]);
      const int b = model.SpeedIndex(model.reduction().group_of_mass[link.to]);
      for (int s = 0; s < kLinkSurfaceCount; ++s) {
        Eigen::VectorXd expected = Eigen::VectorXd::Zero(model.augmented_size());
        expected[f] = rows[s].kpsi;
        expected[a] = rows[s].kv;
        expected[b] = -rows[s].kv;
        expected[one] = rows[s].k0;
        CHECK(model.surfaces().row(kLinkSurfaceCount * k + s).transpose() == expected);
      }
    }
    for (LinkPhase first : RegionsOf(law)) {
      for (LinkPhase other : RegionsOf(law)) {
        const Phases phases{static_cast<char>(first), static_cast<char>(other)};
        std::vector<Model::WatchedSurface> expected;
        for (int k = 0; k < 2; ++k) {
          for (const LinkSurfaceSide& w : WatchedSurfaces(law, static_cast<LinkPhase>(phases[k]))) {
            expected.push_back({kLinkSurfaceCount * k + w.surface, w.side});
          }
        }
        const auto watched = model.Watched(phases);
        REQUIRE(watched.size() == expected.size());
        for (size_t i = 0; i < watched.size(); ++i) {
          CHECK(watched[i].index == expected[i].index);
          CHECK(watched[i].side == expected[i].side);
        }
      }
    }
  }
}
