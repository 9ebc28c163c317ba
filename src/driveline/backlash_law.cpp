#include "millkit/driveline/backlash_law.h"

#include <algorithm>

namespace millkit::driveline {

bool ParseContactLaw(const std::string& text, ContactLaw* law) {
  if (text == "limited") {
    *law = ContactLaw::kLimited;
  } else if (text == "no_pull") {
    *law = ContactLaw::kNoPull;
  } else if (text == "linear") {
    *law = ContactLaw::kLinear;
  } else {
    return false;
  }
  return true;
}

const char* ContactLawName(ContactLaw law) {
  switch (law) {
    case ContactLaw::kLimited:
      return "limited";
    case ContactLaw::kNoPull:
      return "no_pull";
    case ContactLaw::kLinear:
      return "linear";
  }
  return "?";
}

LinkTorqueCoefficients CoefficientsOf(LinkMode mode, double c, double d, double b) {
  const double half = 0.5 * b;
  switch (mode) {
    case LinkMode::kFree:
      return {};
    case LinkMode::kPosSpringDamper:
      return {c, d, -c * half};
    case LinkMode::kPosDoubleSpring:
      return {2.0 * c, 0.0, -2.0 * c * half};
    case LinkMode::kNegSpringDamper:
      return {c, d, c * half};
    case LinkMode::kNegDoubleSpring:
      return {2.0 * c, 0.0, 2.0 * c * half};
  }
  return {};
}

std::vector<LinkPhase> RegionsOf(ContactLaw law) {
  switch (law) {
    case ContactLaw::kLinear:
      return {LinkPhase::kDead, LinkPhase::kPosSpringDamper, LinkPhase::kNegSpringDamper};
    case ContactLaw::kNoPull:
      return {LinkPhase::kDead, LinkPhase::kPosFree, LinkPhase::kPosSpringDamper,
              LinkPhase::kNegFree, LinkPhase::kNegSpringDamper};
    case ContactLaw::kLimited:
      break;
  }
  return {LinkPhase::kDead,
          LinkPhase::kPosFree,
          LinkPhase::kPosSpringDamper,
          LinkPhase::kPosDoubleSpring,
          LinkPhase::kNegFree,
          LinkPhase::kNegSpringDamper,
          LinkPhase::kNegDoubleSpring};
}

const char* LinkPhaseName(LinkPhase phase) {
  static const char* kNames[] = {"dead", "+free", "+sd", "+2c", "-free", "-sd", "-2c"};
  return kNames[static_cast<unsigned char>(phase)];
}

LinkMode ModeOf(LinkPhase phase) {
  switch (phase) {
    case LinkPhase::kPosSpringDamper:
      return LinkMode::kPosSpringDamper;
    case LinkPhase::kPosDoubleSpring:
      return LinkMode::kPosDoubleSpring;
    case LinkPhase::kNegSpringDamper:
      return LinkMode::kNegSpringDamper;
    case LinkPhase::kNegDoubleSpring:
      return LinkMode::kNegDoubleSpring;
    default:
      return LinkMode::kFree;
  }
}

LinkTorqueCoefficients CoefficientsOf(LinkPhase phase, double c, double d, double b) {
  return CoefficientsOf(ModeOf(phase), c, d, b);
}

double StiffestPieceStiffness(ContactLaw law, double c) {
  double stiffest = 0.0;
  for (LinkPhase phase : RegionsOf(law)) {
    stiffest = std::max(stiffest, CoefficientsOf(phase, c, 0.0, 0.0).kpsi);
  }
  return stiffest;
}

std::array<LinkSurfaceRow, kLinkSurfaceCount> LinkSurfaceRows(double c, double d, double b) {
  const double half = 0.5 * b;
  std::array<LinkSurfaceRow, kLinkSurfaceCount> rows;
  rows[kS0] = {1.0, 0.0, -half};
  rows[kS1] = {1.0, 0.0, half};
  // S2 = c(ψ − b/2) + d ψ',  S3 = d ψ' − c(ψ − b/2); S4, S5 the same with ψ + b/2.
  for (int s : {kS2, kS3, kS4, kS5}) {
    const double sign_c = (s == kS2 || s == kS4) ? 1.0 : -1.0;
    const double offset = (s == kS2 || s == kS3) ? -half : half;
    rows[s] = {sign_c * c, d, sign_c * c * offset};
  }
  return rows;
}

LinkPhase PhaseFromSides(ContactLaw law, const int* s) {
  switch (law) {
    case ContactLaw::kLinear:
      if (s[kS0] > 0) return LinkPhase::kPosSpringDamper;
      if (s[kS1] < 0) return LinkPhase::kNegSpringDamper;
      return LinkPhase::kDead;
    case ContactLaw::kNoPull:
      if (s[kS0] > 0) return s[kS2] > 0 ? LinkPhase::kPosSpringDamper : LinkPhase::kPosFree;
      if (s[kS1] < 0) return s[kS4] < 0 ? LinkPhase::kNegSpringDamper : LinkPhase::kNegFree;
      return LinkPhase::kDead;
    case ContactLaw::kLimited:
      if (s[kS0] > 0) {
        if (s[kS2] <= 0) return LinkPhase::kPosFree;
        return s[kS3] < 0 ? LinkPhase::kPosSpringDamper : LinkPhase::kPosDoubleSpring;
      }
      if (s[kS1] < 0) {
        if (s[kS4] >= 0) return LinkPhase::kNegFree;
        return s[kS5] > 0 ? LinkPhase::kNegSpringDamper : LinkPhase::kNegDoubleSpring;
      }
      return LinkPhase::kDead;
  }
  return LinkPhase::kDead;
}

WatchedLinkSurfaces WatchedSurfaces(ContactLaw law, LinkPhase phase) {
  WatchedLinkSurfaces watched;
  auto add = [&](int surface, int side) { watched.list[watched.count++] = {surface, side}; };
  switch (phase) {
    case LinkPhase::kDead:
      add(kS0, -1);
      add(kS1, 1);
      break;
    case LinkPhase::kPosFree:
      add(kS0, 1);
      add(kS2, -1);
      break;
    case LinkPhase::kPosSpringDamper:
      add(kS0, 1);
      if (law != ContactLaw::kLinear) add(kS2, 1);
      if (law == ContactLaw::kLimited) add(kS3, -1);
      break;
    case LinkPhase::kPosDoubleSpring:
      add(kS0, 1);
      add(kS2, 1);
      add(kS3, 1);
      break;
    case LinkPhase::kNegFree:
      add(kS1, -1);
      add(kS4, 1);
      break;
    case LinkPhase::kNegSpringDamper:
      add(kS1, -1);
      if (law != ContactLaw::kLinear) add(kS4, -1);
      if (law == ContactLaw::kLimited) add(kS5, 1);
      break;
    case LinkPhase::kNegDoubleSpring:
      add(kS1, -1);
      add(kS4, -1);
      add(kS5, -1);
      break;
  }
  return watched;
}

}  // namespace millkit::driveline
