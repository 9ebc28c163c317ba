#include "millkit/driveline/backlash_law.h"

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

}  // namespace millkit::driveline
