#include "cut/sheet.h"

#include <algorithm>
#include <cmath>

namespace incise::cut_detail {

namespace {
// Relative tolerance of "in the plane" and "collinear": blade positions a scene or a user
// computes as start + f * sweep are coplanar only up to rounding.
constexpr double kPlanarTol = 1e-9;

// The turn at x on the way p -> x -> q (the ring runs counter-clockwise about n): convex, or
// reflex with x within `tol` (a length) of the line p-q, which counts as straight: a hand's
// wobble or single-precision input bends the swept polygon's sides by that little (0: rounding
// only). `collinear`: straight within the same bounds (x may be merged away).
bool turn_ok(const Vec3& p, const Vec3& x, const Vec3& q, const Vec3& n, bool* collinear, double tol = 0) {
  const Vec3 e1 = x - p, e2 = q - x;
  const double l = e1.norm() * e2.norm();
  const double c = e1.cross(e2).dot(n);
  const double pq = (q - p).norm();
  const bool near_line = tol > 0 && pq > 0 && std::abs((x - p).cross(q - p).dot(n)) <= tol * pq;
  *collinear = l == 0 || ((std::abs(c) <= kPlanarTol * l || near_line) && e1.dot(e2) > 0);
  return c >= -kPlanarTol * l || (near_line && e1.dot(e2) > 0);
}
}  // namespace

std::optional<Sheet> Sheet::start(const BladeSegment& from, const BladeSegment& blade, double tol) {
  BladeSegment to = blade;
  auto tris = swept_triangles(from, to);
  if (tris.empty()) return std::nullopt;
  Sheet s;
  s.tol_ = tol;
  s.plane_ = tris[0];
  s.normal_ = tris[0].normal().normalized();
  for (const Vec3& x : {from.a, from.b, to.a, to.b}) s.scale_ = std::max(s.scale_, (x - from.a).norm());
  if (tris.size() == 2) {
    const double off = s.normal_.dot(to.a - s.plane_.p[0]);
    if (std::abs(off) > kPlanarTol * s.scale_) {
      if (!(std::abs(off) <= tol) || !(s.normal_.norm() > 0)) return std::nullopt;
      to.a -= off * s.normal_;
      tris = swept_triangles(from, to);
    }
    if (tris.size() == 2 && !(tris[1].normal().dot(s.normal_) > 0)) return std::nullopt;
  }
  for (const Vec3& x : {from.a, from.b, to.b, to.a})
    if (s.ring_.empty() || !(x == s.ring_.back())) {
      s.ring_.push_back(x);
      s.keep_.push_back(x == from.a || x == from.b);
    }
  if (s.ring_.size() > 3 && s.ring_.back() == s.ring_.front()) {
    s.ring_.pop_back();
    s.keep_.pop_back();
  }
  s.front_ = std::size_t(std::find(s.ring_.begin(), s.ring_.end(), to.b) - s.ring_.begin());
  if (s.ring_.size() < 3 || s.front_ >= s.ring_.size() || !s.convex()) return std::nullopt;
  s.rebuild_piece();
  return s;
}

BladeSegment Sheet::front() const { return {ring_[(front_ + 1) % ring_.size()], ring_[front_]}; }

void Sheet::set_back_is_crease(bool crease) {
  back_crease_ = crease;
  rebuild_piece();
}

bool Sheet::convex() const {
  const std::size_t n = ring_.size();
  for (std::size_t i = 0; i < n; ++i) {
    bool col = false;
    if (!turn_ok(ring_[(i + n - 1) % n], ring_[i], ring_[(i + 1) % n], normal_, &col, tol_)) return false;
  }
  return true;
}

double Sheet::deviation(const BladeSegment& b) const {
  return std::max(std::abs(normal_.dot(b.a - plane_.p[0])), std::abs(normal_.dot(b.b - plane_.p[0])));
}

bool Sheet::extend(const BladeSegment& blade, double tol) {
  const BladeSegment from = front();
  BladeSegment to = blade;
  const double old_tol = tol_;
  tol_ = tol;
  // Within the tolerance of the plane: projected onto it (an end within rounding of the plane
  // is kept as it is, so a straight sweep gives the same polygon with or without a tolerance).
  for (Vec3* x : {&to.a, &to.b}) {
    const double off = normal_.dot(*x - plane_.p[0]);
    const double exact = kPlanarTol * std::max(scale_, (*x - plane_.p[0]).norm());
    if (std::abs(off) > exact && std::abs(off) <= tol) *x -= off * normal_;
  }
  const auto tris = swept_triangles(from, to);
  if (tris.empty()) return true;  // the blade did not move: nothing swept
  double scale = scale_;
  for (const Vec3& x : {to.a, to.b}) scale = std::max(scale, (x - plane_.p[0]).norm());
  for (const CutTriangle& t : tris)
    if (!(t.normal().dot(normal_) > 0)) { tol_ = old_tol; return false; }  // folds back over the sheet
  for (const Vec3& x : {to.a, to.b})
    if (std::abs(normal_.dot(x - plane_.p[0])) > kPlanarTol * scale) { tol_ = old_tol; return false; }
  std::vector<Vec3> ring;
  std::vector<bool> keep;
  for (std::size_t i = 0; i < ring_.size(); ++i) {
    ring.push_back(ring_[i]);
    keep.push_back(keep_[i]);
    if (i != front_) continue;
    if (!(to.b == from.b)) {
      ring.push_back(to.b);
      keep.push_back(false);
    }
    if (!(to.a == from.a)) {
      ring.push_back(to.a);
      keep.push_back(false);
    }
  }
  // Merge points the sides pass straight through (not the back edge's ends, which an earlier
  // sheet may share as a crease, nor the front's).
  for (bool merged = true; merged && ring.size() > 3;) {
    merged = false;
    const std::size_t n = ring.size();
    for (std::size_t i = 0; i < n; ++i) {
      if (keep[i] || ring[i] == to.a || ring[i] == to.b) continue;
      bool col = false;
      turn_ok(ring[(i + n - 1) % n], ring[i], ring[(i + 1) % n], normal_, &col, tol);
      if (!col) continue;
      ring.erase(ring.begin() + std::ptrdiff_t(i));
      keep.erase(keep.begin() + std::ptrdiff_t(i));
      merged = true;
      break;
    }
  }
  std::vector<Vec3> old_ring = std::move(ring_);
  std::vector<bool> old_keep = std::move(keep_);
  const std::size_t old_front = front_;
  ring_ = std::move(ring);
  keep_ = std::move(keep);
  front_ = std::size_t(std::find(ring_.begin(), ring_.end(), to.b) - ring_.begin());
  if (front_ >= ring_.size() || !(ring_[(front_ + 1) % ring_.size()] == to.a) || !convex()) {
    ring_ = std::move(old_ring);
    keep_ = std::move(old_keep);
    front_ = old_front;
    tol_ = old_tol;
    return false;
  }
  scale_ = scale;
  rebuild_piece();
  return true;
}

void Sheet::rebuild_piece() {
  Piece p;
  const std::size_t n = ring_.size();
  for (std::size_t i = 1; i + 1 < n; ++i) {
    const CutTriangle t{{ring_[0], ring_[i], ring_[i + 1]}};
    if (t.normal().norm() > 0) p.triangles.push_back(t);
  }
  if (p.triangles.empty()) p.triangles.push_back(plane_);
  for (std::size_t i = 0; i < n; ++i) p.boundary.push_back({ring_[i], ring_[(i + 1) % n]});
  finish_piece(p);
  p.plane = plane_;
  p.normal = normal_;
  if (back_crease_) p.rim[0] = false;
  piece_ = std::move(p);
}

}  // namespace incise::cut_detail
