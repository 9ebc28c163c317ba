// Wall-clock guards in tests (a bound against hangs, not a speed claim) are written for the
// Release build. A sanitizer build (MILLKIT_SANITIZE: ASan+UBSan, -O1) runs the same code several
// times slower, so its guards are this many times longer. The Release guard is unchanged.
#pragma once

namespace millkit::testing {

#ifdef MILLKIT_SANITIZE
inline constexpr double kWallGuardScale = 10.0;
#else
inline constexpr double kWallGuardScale = 1.0;
#endif

}  // namespace millkit::testing
