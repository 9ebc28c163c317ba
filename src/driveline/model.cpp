#include "millkit/driveline/model.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include "millkit/driveline/natural_frequencies.h"
#include "millkit/io/input_error.h"
#include "millkit/io/number_format.h"

namespace millkit::driveline {
namespace {

constexpr double kPi = 3.14159265358979323846;
// A surface value this small against the size of its terms is zero to roundoff.
constexpr double kRoundoffZero = 1e-14;
// A static torque this small against the loads is no torque (the link rests in its gap).
constexpr double kNoStaticTorque = 1e-12;
// Surfaces per drive (see model.h); a backlash link's six are the contact law's (backlash_law.h).
enum DriveSurface { kD0 = 0, kD1 };

// Masses on the `to` side of scene link `link` (the subtree B of SPEC §2.5).
std::vector<int> ToSideMasses(const Scene& scene, int link) {
  const int n = static_cast<int>(scene.masses.size());
  std::vector<std::vector<int>> neighbours(n);
  for (int l = 0; l < static_cast<int>(scene.links.size()); ++l) {
    if (l == link) continue;
    neighbours[scene.links[l].from].push_back(scene.links[l].to);
    neighbours[scene.links[l].to].push_back(scene.links[l].from);
  }
  std::vector<bool> seen(n, false);
  std::vector<int> stack{scene.links[link].to}, subtree;
  seen[scene.links[link].to] = true;
  while (!stack.empty()) {
    const int i = stack.back();
    stack.pop_back();
    subtree.push_back(i);
    for (int j : neighbours[i]) {
      if (!seen[j]) {
        seen[j] = true;
        stack.push_back(j);
      }
    }
  }
  return subtree;
}

double TwistFromTorque(const Link& link, double torque, double load_scale) {
  if (std::abs(torque) <= kNoStaticTorque * load_scale) {
    return link.gap_position * 0.5 * link.backlash_rad;
  }
  return (torque > 0.0 ? 1.0 : -1.0) * QuasiStaticTwist(link, torque);
}

}  // namespace

Reduction ReduceToBand(const Scene& scene) {
  const int n = static_cast<int>(scene.masses.size());
  Reduction reduction;
  reduction.link_rigid.assign(scene.links.size(), false);
  std::vector<int> root(n);
  std::iota(root.begin(), root.end(), 0);
  std::vector<double> inertia(n);
  std::vector<std::string> label(n);
  for (int i = 0; i < n; ++i) {
    inertia[i] = scene.masses[i].inertia_kg_m2;
    label[i] = scene.masses[i].name;
  }
  auto find = [&](int i) {
    while (root[i] != i) i = root[i];
    return i;
  };
  if (scene.band_Hz) {
    std::vector<bool> refused(scene.links.size(), false);
    while (true) {
      int best = -1;
      double best_hz = 0.0;
      for (int l = 0; l < static_cast<int>(scene.links.size()); ++l) {
        const Link& link = scene.links[l];
        if (reduction.link_rigid[l] || refused[l] || link.backlash_rad > 0.0) continue;
        const int a = find(link.from), b = find(link.to);
        const double hz =
            std::sqrt(link.stiffness_Nm_per_rad * (1.0 / inertia[a] + 1.0 / inertia[b])) /
            (2.0 * kPi);
        if (hz > best_hz) {
          best = l;
          best_hz = hz;
        }
      }
      if (best < 0) break;
      // Far above means above the band AND above every mode the model keeps (gap contacts of
      // other links included): an impact excites the kept modes, and through them the link.
      Reduction tentative = reduction;
      tentative.link_rigid[best] = true;
      tentative.group_of_mass.resize(n);
      for (int i = 0; i < n; ++i) tentative.group_of_mass[i] = find(i);
      const int a0 = find(scene.links[best].from), b0 = find(scene.links[best].to);
      std::vector<int> number(n, -1);
      int count = 0;
      for (int i = 0; i < n; ++i) {
        int r = tentative.group_of_mass[i] == b0 ? a0 : tentative.group_of_mass[i];
        if (number[r] < 0) number[r] = count++;
        tentative.group_of_mass[i] = number[r];
      }
      const double kept_hz = HighestModeHz(scene, tentative);
      const double threshold = kBandFactor * std::max(*scene.band_Hz, kept_hz);
      if (best_hz < threshold) {
        refused[best] = true;
        continue;
      }
      const Link& link = scene.links[best];
      const int a = find(link.from), b = find(link.to);
      reduction.link_rigid[best] = true;
      std::ostringstream line;
      line << "link '" << link.name << "' (" << FormatNumber(std::round(best_hz))
           << " Hz >= " << kBandFactor << " x max(band " << FormatNumber(*scene.band_Hz)
           << " Hz, fastest kept mode " << FormatNumber(std::round(kept_hz))
           << " Hz)) made rigid: " << label[a] << " + " << label[b] << " merged";
      reduction.report.push_back(line.str());
      root[b] = a;
      inertia[a] += inertia[b];
      label[a] += "+" + label[b];
    }
  }
  reduction.group_of_mass.assign(n, -1);
  std::vector<int> group_of_root(n, -1);
  int groups = 0;
  for (int i = 0; i < n; ++i) {
    const int r = find(i);
    if (group_of_root[r] < 0) group_of_root[r] = groups++;
    reduction.group_of_mass[i] = group_of_root[r];
  }
  return reduction;
}

double HighestModeHz(const Scene& scene, const Reduction& reduction) {
  const std::vector<double> hz = ModalFrequenciesHz(scene, reduction, GapStiffness::kStiffestPiece);
  return hz.size() < 2 ? 0.0 : hz.back();
}

void CheckSampleRate(const Scene& user_scene) {
  const Scene scene = ReducedScene(user_scene);
  const Reduction reduction = ReduceToBand(scene);
  const double f_max = HighestModeHz(scene, reduction);
  const double needed = kSamplesPerFastestPeriod * f_max;
  if (!std::isfinite(needed)) {
    throw InputError(
        (scene.file.empty() ? std::string("<scene>") : scene.file) +
        ": [[link]] stiffness / [[mass]] inertia: the ratio c/J of some link overflows "
        "double precision (its natural frequency is not finite); the rule is that "
        "every stiffness over the inertias it joins stays below about 1e300");
  }
  if (scene.sample_rate_Hz < needed) {
    throw InputError(
        (scene.file.empty() ? std::string("<scene>") : scene.file) +
        ": [scene] key 'sample_rate': " + FormatNumber(scene.sample_rate_Hz) +
        " Hz cannot resolve the fastest mode of the model (" + FormatNumber(std::round(f_max)) +
        " Hz); the rule is sample_rate >= " + FormatNumber(kSamplesPerFastestPeriod) +
        " x fastest mode = " + FormatNumber(std::ceil(needed)) +
        " Hz. Raise sample_rate, or set [scene] band to make links far above it rigid");
  }
}

std::vector<double> SourceTorquesAt(const Scene& scene, double t) {
  std::vector<double> torque(scene.masses.size(), 0.0);
  for (const auto& source : scene.torques) torque[source.mass] += source.ValueAt(t);
  return torque;
}

double SteadyDriveTorque(const Scene& scene, double t) {
  if (!scene.drive) return 0.0;
  const auto loads = SourceTorquesAt(scene, t);
  const double net = std::accumulate(loads.begin(), loads.end(), 0.0);
  return std::clamp(-net, -scene.drive->limit_Nm, scene.drive->limit_Nm);
}

std::vector<double> QuasiStaticLinkTorques(const Scene& scene,
                                           const std::vector<double>& mass_torques) {
  double total_j = 0.0, total_m = 0.0;
  for (size_t i = 0; i < scene.masses.size(); ++i) {
    total_j += scene.masses[i].inertia_kg_m2;
    total_m += mass_torques[i];
  }
  const double epsilon = total_m / total_j;
  std::vector<double> torque(scene.links.size());
  for (size_t l = 0; l < scene.links.size(); ++l) {
    double j_b = 0.0, m_b = 0.0;
    for (int i : ToSideMasses(scene, static_cast<int>(l))) {
      j_b += scene.masses[i].inertia_kg_m2;
      m_b += mass_torques[i];
    }
    torque[l] = j_b * epsilon - m_b;
  }
  return torque;
}

std::vector<double> StaticLinkTorques(const Scene& user_scene) {
  const Scene scene = ReducedScene(user_scene);
  auto torques = SourceTorquesAt(scene, scene.duration_s);
  if (scene.drive) torques[scene.drive->mass] += SteadyDriveTorque(scene, scene.duration_s);
  std::vector<double> link_torque = QuasiStaticLinkTorques(scene, torques);
  const ShaftFactors k = ComputeShaftFactors(user_scene);
  for (size_t l = 0; l < link_torque.size(); ++l) link_torque[l] /= k.link[l];
  return link_torque;
}

Model::Model(Scene scene, Use use) : user_scene_(std::move(scene)) {
  ValidateScene(user_scene_);
  // Everything below works on the reference shaft; outputs go back through the factors.
  scene_ = ReducedScene(user_scene_);
  shaft_factors_ = ComputeShaftFactors(user_scene_);
  reduction_ = ReduceToBand(scene_);
  const int groups =
      1 + *std::max_element(reduction_.group_of_mass.begin(), reduction_.group_of_mass.end());
  group_inertia_.assign(groups, 0.0);
  for (size_t i = 0; i < scene_.masses.size(); ++i) {
    group_inertia_[reduction_.group_of_mass[i]] += scene_.masses[i].inertia_kg_m2;
  }
  flexible_index_.assign(scene_.links.size(), -1);
  rigid_to_side_masses_.assign(scene_.links.size(), {});
  for (int l = 0; l < static_cast<int>(scene_.links.size()); ++l) {
    if (reduction_.link_rigid[l]) {
      const int group = reduction_.group_of_mass[scene_.links[l].to];
      for (int i : ToSideMasses(scene_, l)) {
        if (reduction_.group_of_mass[i] == group) rigid_to_side_masses_[l].push_back(i);
      }
      continue;
    }
    flexible_index_[l] = static_cast<int>(flexible_links_.size());
    backlash_of_flexible_.push_back(-1);
    if (scene_.links[l].backlash_rad > 0.0) {
      backlash_of_flexible_.back() = static_cast<int>(backlash_links_.size());
      backlash_links_.push_back(flexible_index_[l]);
    }
    flexible_links_.push_back(l);
  }
  drive_base_ = flexible_link_count() + groups;
  filter_base_ = drive_base_ + (has_drive() ? 2 : 0);
  filter_index_.assign(scene_.links.size(), -1);
  for (int l = 0; l < static_cast<int>(scene_.links.size()); ++l) {
    if (scene_.links[l].recorder_lowpass_Hz <= 0.0) continue;
    filter_index_[l] = filter_base_ + static_cast<int>(filtered_links_.size());
    filtered_links_.push_back(l);
  }
  nx_ = filter_base_ + static_cast<int>(filtered_links_.size());
  nw_ = 1 + static_cast<int>(scene_.torques.size());
  BuildSurfaces();
  // All three depend on the scene only; every run needs them. The phases do not read the
  // recorder low-pass states (no surface does, and nothing else depends on them), so they are
  // found before those states are settled on the initial torques.
  initial_state_ = ComputeInitialState();
  initial_phases_ = InitialPhases(initial_state_);
  SettleFilters(&initial_state_);
  if (use == Use::kRun) state_scale_ = ComputeStateScale();
}

Eigen::VectorXd Model::StateScale() const {
  if (state_scale_.size() == 0) {
    throw std::logic_error("Model::StateScale: the model was built for its coefficients only");
  }
  return state_scale_;
}

void Model::BuildSurfaces() {
  const int count = kLinkSurfaceCount * backlash_link_count() + (has_drive() ? 2 : 0);
  surfaces_ = Eigen::MatrixXd::Zero(count, augmented_size());
  default_side_.assign(count, 1);
  side_from_motion_.assign(count, 1);
  const int one = nx_;  // column of the constant forcing 1
  for (int k = 0; k < backlash_link_count(); ++k) {
    const int f = backlash_links_[k];
    const Link& link = scene_.links[flexible_links_[f]];
    const int a = SpeedIndex(reduction_.group_of_mass[link.from]);
    const int b = SpeedIndex(reduction_.group_of_mass[link.to]);
    // The law's rows over (ψ, ψ', 1), with ψ' = ω_a − ω_b.
    const auto rows =
        LinkSurfaceRows(link.stiffness_Nm_per_rad, link.damping_Nms_per_rad, link.backlash_rad);
    for (int s = 0; s < kLinkSurfaceCount; ++s) {
      auto row = surfaces_.row(kLinkSurfaceCount * k + s);
      row(f) = rows[s].kpsi;
      row(one) = rows[s].k0;
      row(a) += rows[s].kv;
      row(b) -= rows[s].kv;
      default_side_[kLinkSurfaceCount * k + s] = kLinkDefaultSides[s];
      side_from_motion_[kLinkSurfaceCount * k + s] = kLinkSideFromMotion[s] ? 1 : 0;
    }
  }
  if (has_drive()) {
    const Drive& drive = *scene_.drive;
    const int base = kLinkSurfaceCount * backlash_link_count();
    const int w = SpeedIndex(reduction_.group_of_mass[drive.mass]);
    const int integral = drive_base_;
    for (int s : {kD0, kD1}) {
      auto row = surfaces_.row(base + s);
      row(one) = drive.kp * drive.speed_ref_rad_per_s + (s == kD0 ? -1.0 : 1.0) * drive.limit_Nm;
      row(w) = -drive.kp;
      row(integral) = drive.ki;
    }
    default_side_[base + kD0] = -1;
    default_side_[base + kD1] = 1;
  }
  abs_surfaces_ = surfaces_.cwiseAbs();
}

void Model::StateAndInputBlocks(const Phases& phases, Eigen::MatrixXd* m) const {
  auto a = m->topLeftCorner(nx_, nx_);
  auto b = m->block(0, nx_, nx_, nw_);
  for (int f = 0; f < flexible_link_count(); ++f) {
    const Link& link = scene_.links[flexible_links_[f]];
    const int ga = reduction_.group_of_mass[link.from], gb = reduction_.group_of_mass[link.to];
    const int wa = SpeedIndex(ga), wb = SpeedIndex(gb);
    a(f, wa) += 1.0;
    a(f, wb) -= 1.0;
    const LinkTorqueCoefficients k = FlexibleLinkCoefficients(phases, f);
    // m = kψ ψ + kv (ω_a − ω_b) + k0; `from` gets −m, `to` gets +m.
    for (const auto& [row, sign] :
         {std::pair{wa, -1.0 / group_inertia_[ga]}, std::pair{wb, 1.0 / group_inertia_[gb]}}) {
      a(row, f) += sign * k.kpsi;
      a(row, wa) += sign * k.kv;
      a(row, wb) -= sign * k.kv;
      b(row, 0) += sign * k.k0;
    }
  }
  for (size_t s = 0; s < scene_.torques.size(); ++s) {
    const int g = reduction_.group_of_mass[scene_.torques[s].mass];
    b(SpeedIndex(g), 1 + static_cast<int>(s)) += 1.0 / group_inertia_[g];
  }
  if (has_drive()) {
    const Drive& drive = *scene_.drive;
    const int g = reduction_.group_of_mass[drive.mass];
    const int w = SpeedIndex(g), integral = drive_base_, torque = drive_base_ + 1;
    a(integral, w) -= 1.0;
    b(integral, 0) += drive.speed_ref_rad_per_s;
    a(w, torque) += 1.0 / group_inertia_[g];
    const auto phase = static_cast<DrivePhase>(phases.back());
    const double inv_lag = 1.0 / drive.lag_s;
    a(torque, torque) -= inv_lag;
    switch (phase) {
      case DrivePhase::kLinear:
        b(torque, 0) += inv_lag * drive.kp * drive.speed_ref_rad_per_s;
        a(torque, w) -= inv_lag * drive.kp;
        a(torque, integral) += inv_lag * drive.ki;
        break;
      case DrivePhase::kSaturatedHigh:
        b(torque, 0) += inv_lag * drive.limit_Nm;
        break;
      case DrivePhase::kSaturatedLow:
        b(torque, 0) -= inv_lag * drive.limit_Nm;
        break;
    }
  }
  if (filtered_links_.empty()) return;
  // y' = a (T z − y) with T the link's own torque row in these phases (a rigid link's reads the
  // accelerations, which do not depend on y).
  const Eigen::MatrixXd torque = OwnLinkTorqueRows(phases, *m);
  for (const int l : filtered_links_) {
    const int y = filter_index_[l];
    const double rate = 2.0 * M_PI * scene_.links[l].recorder_lowpass_Hz;
    a.row(y) = rate * torque.row(l).head(nx_);
    b.row(y) = rate * torque.row(l).segment(nx_, nw_);
    a(y, y) -= rate;
  }
}

void Model::LinearPieces(const Phases& phases, Eigen::MatrixXd* a, Eigen::MatrixXd* b) const {
  const int n = augmented_size();
  Eigen::MatrixXd m = Eigen::MatrixXd::Zero(n, n);
  StateAndInputBlocks(phases, &m);
  *a = m.topLeftCorner(nx_, nx_);
  *b = m.block(0, nx_, nx_, nw_);
}

Eigen::MatrixXd Model::SystemMatrix(const Phases& phases) const {
  const int n = augmented_size();
  Eigen::MatrixXd m = Eigen::MatrixXd::Zero(n, n);
  StateAndInputBlocks(phases, &m);
  // w' = s (the slope block); the constant 1 has slope 0 by construction of SetForcing.
  m.block(nx_, nx_ + nw_, nw_, nw_).setIdentity();
  return m;
}

std::vector<Model::WatchedSurface> Model::Watched(const Phases& phases) const {
  std::vector<WatchedSurface> watched;
  for (int k = 0; k < backlash_link_count(); ++k) {
    const int base = kLinkSurfaceCount * k;
    for (const LinkSurfaceSide& w :
         WatchedSurfaces(scene_.contact, static_cast<LinkPhase>(phases[k]))) {
      watched.push_back({base + w.surface, w.side});
    }
  }
  if (has_drive()) {
    const int base = kLinkSurfaceCount * backlash_link_count();
    switch (static_cast<DrivePhase>(phases.back())) {
      case DrivePhase::kLinear:
        watched.push_back({base + kD0, -1});
        watched.push_back({base + kD1, 1});
        break;
      case DrivePhase::kSaturatedHigh:
        watched.push_back({base + kD0, 1});
        break;
      case DrivePhase::kSaturatedLow:
        watched.push_back({base + kD1, -1});
        break;
    }
  }
  return watched;
}

Phases Model::Classify(const Eigen::VectorXd& z, const Eigen::VectorXd& zdot,
                       const Eigen::VectorXd& zddot,
                       const std::vector<KnownSide>& known_sides) const {
  return Classify(z, std::vector<Eigen::VectorXd>{zdot, zddot}, known_sides);
}

bool Model::KeptSide(int surface, const std::vector<KnownSide>& known_sides, const Phases& before,
                     int* side) const {
  const int k = surface / kLinkSurfaceCount;
  if (k >= backlash_link_count()) return false;
  for (const KnownSide& known : known_sides) {
    if (known.surface / kLinkSurfaceCount == k) return false;  // the event involves the link
  }
  for (const LinkSurfaceSide& w :
       WatchedSurfaces(scene_.contact, static_cast<LinkPhase>(before[k]))) {
    if (kLinkSurfaceCount * k + w.surface == surface) {
      *side = w.side;
      return true;
    }
  }
  return false;
}

Phases Model::Classify(const Eigen::VectorXd& z, const std::vector<Eigen::VectorXd>& derivatives,
                       const std::vector<KnownSide>& known_sides, const Phases* before) const {
  const int count = surface_count();
  // Called at every switching event: work space on the stack for the usual sizes.
  const int n = static_cast<int>(z.size());
  constexpr int kStack = 128;
  int stack_side[kStack];
  double stack_values[3 * kStack];
  std::vector<int> heap_side;
  std::vector<double> heap_values;
  int* side = stack_side;
  double* values = stack_values;
  if (count > kStack || n > kStack) {
    heap_side.resize(count);
    heap_values.resize(2 * count + n);
    side = heap_side.data();
    values = heap_values.data();
  }
  Eigen::Map<Eigen::VectorXd> g(values, count), scale(values + count, count);
  Eigen::Map<Eigen::VectorXd> abs_z(values + 2 * static_cast<std::ptrdiff_t>(count), n);
  g.noalias() = surfaces_ * z;
  // The size of each surface's terms, |G| |z|: what "zero to roundoff" is measured against.
  abs_z = z.cwiseAbs();
  scale.noalias() = abs_surfaces_ * abs_z;
  for (int j = 0; j < count; ++j) {
    const auto known = std::find_if(known_sides.begin(), known_sides.end(),
                                    [j](const KnownSide& k) { return k.surface == j; });
    if (known != known_sides.end()) {
      side[j] = known->side;
      continue;
    }
    if (std::abs(g[j]) > kRoundoffZero * scale[j]) {
      side[j] = g[j] > 0.0 ? 1 : -1;
      continue;
    }
    // On the surface to roundoff (rare): the motion decides, by its first moving derivative
    // (except at the limited law's corner: kLinkSideFromMotion).
    side[j] = default_side_[j];
    if (side_from_motion_[j] == 0) {
      if (before != nullptr) KeptSide(j, known_sides, *before, &side[j]);
      continue;
    }
    for (const Eigen::VectorXd& derivative : derivatives) {
      // An order the caller left empty (the exact solver stops at a zero derivative) tells
      // nothing (and a dot product of unequal sizes breaks Eigen's contract).
      if (derivative.size() != z.size()) continue;
      const double gk = surfaces_.row(j).dot(derivative);
      const double scale_k = abs_surfaces_.row(j).dot(derivative.cwiseAbs());
      if (std::abs(gk) > kRoundoffZero * scale_k && gk != 0.0) {
        side[j] = gk > 0.0 ? 1 : -1;
        break;
      }
    }
  }
  Phases phases(backlash_link_count() + (has_drive() ? 1 : 0), '\0');
  for (int k = 0; k < backlash_link_count(); ++k) {
    const int* link_side = side + static_cast<std::ptrdiff_t>(kLinkSurfaceCount) * k;
    phases[k] = static_cast<char>(PhaseFromSides(scene_.contact, link_side));
  }
  if (has_drive()) {
    const int base = kLinkSurfaceCount * backlash_link_count();
    DrivePhase drive = DrivePhase::kLinear;
    if (side[base + kD0] > 0) drive = DrivePhase::kSaturatedHigh;
    if (side[base + kD1] < 0) drive = DrivePhase::kSaturatedLow;
    phases.back() = static_cast<char>(drive);
  }
  return phases;
}

Phases Model::InitialPhases(const Eigen::VectorXd& z0) const {
  Phases phases = Classify(z0, std::vector<Eigen::VectorXd>{}, {});
  // The tie-breaks read the motion, which depends on the phases: iterate to a fixed point. At
  // rest the motion may start at any order up to the size of the state (Cayley-Hamilton: when
  // the first n derivatives vanish, all do).
  std::vector<Eigen::VectorXd> derivatives(z0.size());
  for (int iteration = 0; iteration < 8; ++iteration) {
    const Eigen::MatrixXd m = SystemMatrix(phases);
    derivatives[0].noalias() = m * z0;
    for (size_t k = 1; k < derivatives.size(); ++k) {
      derivatives[k].noalias() = m * derivatives[k - 1];
    }
    const Phases next = Classify(z0, derivatives, {});
    if (next == phases) break;
    phases = next;
  }
  return phases;
}

Eigen::VectorXd Model::ComputeInitialState() const {
  Eigen::VectorXd z = Eigen::VectorXd::Zero(augmented_size());
  auto torques = SourceTorquesAt(scene_, 0.0);
  double load_scale = 0.0;
  for (double t : torques) load_scale += std::abs(t);
  double drive_torque = 0.0;
  if (has_drive()) {
    drive_torque = SteadyDriveTorque(scene_, 0.0);
    torques[scene_.drive->mass] += drive_torque;
    load_scale += std::abs(drive_torque);
  }
  const auto link_torque = QuasiStaticLinkTorques(scene_, torques);
  for (int f = 0; f < flexible_link_count(); ++f) {
    const int l = flexible_links_[f];
    z[f] = TwistFromTorque(scene_.links[l], link_torque[l], load_scale);
  }
  for (int g = 0; g < group_count(); ++g) z[SpeedIndex(g)] = scene_.initial_speed_rad_per_s;
  if (has_drive()) {
    const Drive& drive = *scene_.drive;
    const double error = drive.speed_ref_rad_per_s - scene_.initial_speed_rad_per_s;
    z[drive_base_] = drive.ki > 0.0 ? (drive_torque - drive.kp * error) / drive.ki : 0.0;
    z[drive_base_ + 1] = drive_torque;
  }
  SetForcing(0.0, &z);
  return z;
}

void Model::SettleFilters(Eigen::VectorXd* z) const {
  if (filtered_links_.empty()) return;
  // The recorder's filters start settled on the torques the line starts with.
  const Eigen::MatrixXd torque = OwnLinkTorqueRows(initial_phases_, SystemMatrix(initial_phases_));
  for (const int l : filtered_links_) (*z)[filter_index_[l]] = torque.row(l).dot(*z);
}

void Model::SetForcing(double t, Eigen::VectorXd* z) const {
  (*z)[nx_] = 1.0;
  (*z)[nx_ + nw_] = 0.0;
  for (size_t s = 0; s < scene_.torques.size(); ++s) {
    (*z)[nx_ + 1 + s] = scene_.torques[s].ValueAt(t);
    (*z)[nx_ + nw_ + 1 + s] = scene_.torques[s].SlopeAt(t);
  }
}

LinkTorqueCoefficients Model::FlexibleLinkCoefficients(const Phases& phases, int f) const {
  const Link& link = scene_.links[flexible_links_[f]];
  const int backlash = backlash_of_flexible_[f];
  // A link without backlash is the plain spring-damper m = c ψ + d ψ'.
  if (backlash < 0) return {link.stiffness_Nm_per_rad, link.damping_Nms_per_rad, 0.0};
  return CoefficientsOf(static_cast<LinkPhase>(phases[backlash]), link.stiffness_Nm_per_rad,
                        link.damping_Nms_per_rad, link.backlash_rad);
}

void Model::Outputs(const Phases& phases, const Eigen::VectorXd& z, double* link_torque,
                    double* mass_speed, double* link_twist,
                    const Eigen::MatrixXd* system_matrix) const {
  OwnOutputs(phases, z, link_torque, mass_speed, link_twist, system_matrix);
  for (const int l : filtered_links_) {
    link_torque[l] = z[filter_index_[l]];
    // A rigid link's twist is its reported torque over c, as the exact solver reports it.
    if (reduction_.link_rigid[l])
      link_twist[l] = link_torque[l] / scene_.links[l].stiffness_Nm_per_rad;
  }
}

void Model::OwnOutputs(const Phases& phases, const Eigen::VectorXd& z, double* link_torque,
                       double* mass_speed, double* link_twist,
                       const Eigen::MatrixXd* system_matrix) const {
  // Flexible link torques; kept on the stack for the usual small trees.
  constexpr int kStackLinks = 64;
  double stack_torque[kStackLinks];
  std::vector<double> heap_torque;
  double* flexible_torque = stack_torque;
  if (flexible_link_count() > kStackLinks) {
    heap_torque.resize(flexible_link_count());
    flexible_torque = heap_torque.data();
  }
  for (int f = 0; f < flexible_link_count(); ++f) {
    const int l = flexible_links_[f];
    const Link& link = scene_.links[l];
    const double v = z[SpeedIndex(reduction_.group_of_mass[link.from])] -
                     z[SpeedIndex(reduction_.group_of_mass[link.to])];
    const LinkTorqueCoefficients k = FlexibleLinkCoefficients(phases, f);
    flexible_torque[f] = k.kpsi * z[f] + k.kv * v + k.k0;
    link_torque[l] = flexible_torque[f];
    link_twist[l] = z[f];
  }
  for (size_t i = 0; i < scene_.masses.size(); ++i) {
    mass_speed[i] = z[SpeedIndex(reduction_.group_of_mass[i])];
  }
  if (flexible_link_count() == static_cast<int>(scene_.links.size())) return;
  // Rigid links: the torque that holds the to-side part B of the merged mass on the group's
  // acceleration α, m = Σ_B (J_i α − F_i), F_i all other torques on mass i.
  const Eigen::VectorXd zdot =
      system_matrix != nullptr ? Eigen::VectorXd(*system_matrix * z) : SystemMatrix(phases) * z;
  std::vector<double> force(scene_.masses.size(), 0.0);
  for (size_t s = 0; s < scene_.torques.size(); ++s) {
    force[scene_.torques[s].mass] += z[nx_ + 1 + s];
  }
  if (has_drive()) force[scene_.drive->mass] += z[drive_base_ + 1];
  for (int f = 0; f < flexible_link_count(); ++f) {
    const Link& link = scene_.links[flexible_links_[f]];
    force[link.from] -= flexible_torque[f];
    force[link.to] += flexible_torque[f];
  }
  for (size_t l = 0; l < scene_.links.size(); ++l) {
    if (!reduction_.link_rigid[l]) continue;
    const double alpha = zdot[SpeedIndex(reduction_.group_of_mass[scene_.links[l].to])];
    double m = 0.0;
    for (int i : rigid_to_side_masses_[l]) m += scene_.masses[i].inertia_kg_m2 * alpha - force[i];
    link_torque[l] = m;
    link_twist[l] = m / scene_.links[l].stiffness_Nm_per_rad;
  }
}

Eigen::MatrixXd Model::LinkTorqueRows(const Phases& phases,
                                      const Eigen::MatrixXd& system_matrix) const {
  Eigen::MatrixXd rows = OwnLinkTorqueRows(phases, system_matrix);
  for (const int l : filtered_links_) {
    rows.row(l).setZero();
    rows(l, filter_index_[l]) = 1.0;
  }
  return rows;
}

Eigen::MatrixXd Model::OwnLinkTorqueRows(const Phases& phases,
                                         const Eigen::MatrixXd& system_matrix) const {
  const int links = static_cast<int>(scene_.links.size());
  const int n = augmented_size();
  Eigen::MatrixXd rows = Eigen::MatrixXd::Zero(links, n);
  if (flexible_link_count() < links) {
    // Rigid links mix forces and accelerations: read T off Outputs, one unit vector per column.
    // Outputs adds the constant k0 of each law piece as such (affine in z); it belongs to the
    // column of the forcing component that is always 1.
    Eigen::VectorXd unit = Eigen::VectorXd::Zero(n);
    std::vector<double> offset(links), torque(links), speed(scene_.masses.size()), twist(links);
    OwnOutputs(phases, unit, offset.data(), speed.data(), twist.data(), &system_matrix);
    for (int j = 0; j < n; ++j) {
      unit[j] = 1.0;
      OwnOutputs(phases, unit, torque.data(), speed.data(), twist.data(), &system_matrix);
      for (int l = 0; l < links; ++l) rows(l, j) = torque[l] - offset[l];
      unit[j] = 0.0;
    }
    for (int l = 0; l < links; ++l) rows(l, nx_) += offset[l];
    return rows;
  }
  // The flexible links' torques as in Outputs: m = kψ ψ + kv (ω_from − ω_to) + k0 · 1.
  for (int f = 0; f < flexible_link_count(); ++f) {
    const int l = flexible_links_[f];
    const Link& link = scene_.links[l];
    const LinkTorqueCoefficients k = FlexibleLinkCoefficients(phases, f);
    rows(l, f) += k.kpsi;
    rows(l, SpeedIndex(reduction_.group_of_mass[link.from])) += k.kv;
    rows(l, SpeedIndex(reduction_.group_of_mass[link.to])) -= k.kv;
    rows(l, nx_) += k.k0;
  }
  return rows;
}

Eigen::VectorXd Model::ComputeStateScale() const {
  Eigen::VectorXd scale(nx_);
  const auto final_torque = StaticLinkTorques(scene_);
  const Eigen::VectorXd z0 = InitialState();
  const double speed = std::max(std::abs(scene_.initial_speed_rad_per_s), 1.0);
  for (int f = 0; f < flexible_link_count(); ++f) {
    const Link& link = scene_.links[flexible_links_[f]];
    const double ja = group_inertia_[reduction_.group_of_mass[link.from]];
    const double jb = group_inertia_[reduction_.group_of_mass[link.to]];
    // The twist that balances the speed scale in the link's own mode (ψ' = Δω, Δω' ~ c ψ / J):
    // with it the scaled system matrix has entries near that mode's frequency.
    const double omega_link = std::sqrt(link.stiffness_Nm_per_rad * (1.0 / ja + 1.0 / jb));
    const double twist = QuasiStaticTwist(link, final_torque[flexible_links_[f]]);
    scale[f] = std::max({twist, std::abs(z0[f]), speed / omega_link});
  }
  for (int g = 0; g < group_count(); ++g) scale[SpeedIndex(g)] = speed;
  for (const int l : filtered_links_) scale[filter_index_[l]] = 0.0;
  if (has_drive()) {
    const Drive& drive = *scene_.drive;
    scale[drive_base_] = drive.ki > 0.0 ? drive.limit_Nm / drive.ki : 1.0;
    scale[drive_base_ + 1] = drive.limit_Nm;
  }
  if (filtered_links_.empty()) return scale;
  // A low-pass state's scale is the sum of its torque's terms at their scales (forcing at the
  // sources' peaks), the most over the phase sets of every link in contact, dead, and the
  // initial ones.
  Eigen::VectorXd forcing_scale = Eigen::VectorXd::Ones(nw_);
  for (size_t s = 0; s < scene_.torques.size(); ++s) {
    for (const double v : scene_.torques[s].values_Nm) {
      forcing_scale[1 + s] = std::max(forcing_scale[1 + s], std::abs(v));
    }
  }
  for (const Phases& phases : CouplingPhaseSets()) {
    const Eigen::MatrixXd torque = OwnLinkTorqueRows(phases, SystemMatrix(phases));
    for (const int l : filtered_links_) {
      double terms = 0.0;
      for (int j = 0; j < filter_base_; ++j) terms += std::abs(torque(l, j)) * scale[j];
      for (int w = 0; w < nw_; ++w) terms += std::abs(torque(l, nx_ + w)) * forcing_scale[w];
      double& y = scale[filter_index_[l]];
      y = std::max({y, terms, std::abs(z0[filter_index_[l]]), 1.0});
    }
  }
  return scale;
}

std::vector<Phases> Model::CouplingPhaseSets() const {
  std::vector<Phases> sets{initial_phases_};
  for (const LinkPhase link : {LinkPhase::kPosSpringDamper, LinkPhase::kDead}) {
    Phases phases(backlash_link_count() + (has_drive() ? 1 : 0), static_cast<char>(link));
    if (has_drive()) phases.back() = static_cast<char>(DrivePhase::kLinear);
    sets.push_back(phases);
  }
  return sets;
}

std::string Model::DescribePhases(const Phases& phases) const {
  static const char* kDriveNames[] = {"lin", "sat+", "sat-"};
  std::string text;
  for (int k = 0; k < backlash_link_count(); ++k) {
    text += (text.empty() ? "" : " ") + scene_.links[flexible_links_[backlash_links_[k]]].name +
            ":" + LinkPhaseName(static_cast<LinkPhase>(phases[k]));
  }
  if (has_drive()) {
    text += std::string(text.empty() ? "" : " ") +
            "drive:" + kDriveNames[static_cast<unsigned char>(phases.back())];
  }
  return text;
}

}  // namespace millkit::driveline
