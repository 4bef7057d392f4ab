#include "quality/star_ascent.h"

#include <algorithm>

namespace incise {

AngleQuality OpenStar::at(const Vec3& p, const AngleTargets& t) const {
  AngleQuality w;
  for (std::size_t i = 0; i < tets.size(); ++i) w.combine(one(i, p, t));
  return w;
}

AngleQuality OpenStar::one(std::size_t i, const Vec3& p, const AngleTargets& t) const {
  auto x = tets[i];
  x[slot[i]] = p;
  return angle_quality(x[0], x[1], x[2], x[3], t);
}

double OpenStar::one_q(std::size_t i, const Vec3& p, const AngleTargets& t) const {
  auto x = tets[i];
  x[slot[i]] = p;
  return angle_q(x[0], x[1], x[2], x[3], t);
}

AngleQuality OpenStar::one_angles(std::size_t i, const Vec3& p, const AngleTargets& t) const {
  auto x = tets[i];
  x[slot[i]] = p;
  return angle_quality_angles(x[0], x[1], x[2], x[3], t);
}

double OpenStar::one_radius_ratio(std::size_t i, const Vec3& p) const {
  auto x = tets[i];
  x[slot[i]] = p;
  return angle_radius_ratio(x[0], x[1], x[2], x[3]);
}

namespace {

// Smallest vector in the convex hull of g (Frank-Wolfe; the hull is small).
Vec3 min_norm_in_hull(const std::vector<Vec3>& g) {
  Vec3 x = g.front();
  for (int it = 0; it < 64; ++it) {
    std::size_t best = 0;
    for (std::size_t i = 1; i < g.size(); ++i)
      if (g[i].dot(x) < g[best].dot(x)) best = i;
    const Vec3 d = g[best] - x;
    const double dd = d.squaredNorm();
    if (dd == 0 || x.dot(x) - g[best].dot(x) <= 1e-12 * x.squaredNorm()) break;
    x += std::clamp(-x.dot(d) / dd, 0.0, 1.0) * d;
  }
  return x;
}

}  // namespace

Vec3 ascend(const OpenStar& star, const Vec3& p0, const AngleTargets& tg, const AscentOptions& opt,
            AngleQuality* at_p0, AngleQuality* at_best) {
  // The searches compare q only (one_q, one_angles: the same values without the radius
  // ratio); the radius ratios are added where a trial is taken (better() needs them). qs:
  // each tet's q at p (from the last accepted trial), which the activity test reuses.
  const std::size_t n = star.tets.size();
  std::vector<double> qs(n);
  std::vector<AngleQuality> trial(n);  // each tet's angles at the trial point
  // star.at(p0) tet by tet (the same combine, in the same order), keeping each tet's q.
  AngleQuality orig;
  for (std::size_t i = 0; i < n; ++i) {
    const AngleQuality a = star.one(i, p0, tg);
    qs[i] = a.q;
    orig.combine(a);
  }
  if (at_p0) *at_p0 = orig;
  AngleQuality best = orig;
  Vec3 p = p0, best_p = p0;
  AngleQuality cur = orig;
  const double h = opt.scale, fd = 1e-6 * h;
  std::vector<Vec3> grads;
  std::vector<std::size_t> order;
  for (int it = 0; it < opt.iterations; ++it) {
    grads.clear();
    for (std::size_t i = 0; i < n; ++i) {
      if (qs[i] > cur.q + 1e-3) continue;  // not active
      Vec3 g;
      for (int k = 0; k < 3; ++k) {
        Vec3 e = Vec3::Zero();
        e[k] = fd;
        g[k] = (star.one_q(i, p + e, tg) - star.one_q(i, p - e, tg)) / (2 * fd);
      }
      if (opt.normal) g -= *opt.normal * opt.normal->dot(g);
      if (opt.line) g = *opt.line * opt.line->dot(g);
      grads.push_back(g);
    }
    if (grads.empty()) break;
    const Vec3 d = min_norm_in_hull(grads);
    if (!(d.norm() * h > 1e-9)) break;  // a (nonsmooth) local maximum
    // A trial is taken only if every tet's q is above the current worst: the tets that are
    // worst now go first, and the first one not above it ends the trial (the smallest of the
    // rest could only be lower).
    order.resize(n);
    for (std::size_t i = 0; i < n; ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) { return qs[x] < qs[y] || (qs[x] == qs[y] && x < y); });
    bool stepped = false;
    for (double len = 0.3 * h; len > 1e-3 * h; len *= 0.5) {
      Vec3 at = p + len * d.normalized();
      if (opt.project && !opt.project(at)) continue;
      double q = 1e300;  // AngleQuality's q starts there too (combine takes the min)
      for (std::size_t i : order)
        if (!((q = std::min(q, (trial[i] = star.one_angles(i, at, tg)).q)) > cur.q)) break;
      if (q > cur.q) {
        // star.at(at) but its radius ratio: the angles found above, combined in order.
        p = at;
        cur = AngleQuality{};
        for (std::size_t i = 0; i < n; ++i) {
          cur.combine(trial[i]);  // radius ratio 1 (angle_quality_angles)
          qs[i] = trial[i].q;
        }
        stepped = true;
        break;
      }
    }
    if (!stepped) break;
    // better(star.at(p), orig): its angle conditions first; the radius ratios (the same
    // combine, in order) only when those hold, stopping at the first tet below the bound
    // (the smallest could only be lower: better() fails either way).
    if (cur.q > orig.q + 1e-6 && cur.min_dihedral >= std::min(orig.min_dihedral, tg.min_deg) &&
        cur.max_dihedral <= std::max(orig.max_dihedral, tg.max_deg)) {
      const double need = std::min(orig.radius_ratio, tg.radius_ratio_floor);
      double rr = AngleQuality{}.radius_ratio;
      bool ok = true;
      for (std::size_t i = 0; i < n && ok; ++i) ok = (rr = std::min(rr, star.one_radius_ratio(i, p))) >= need;
      if (ok) {
        cur.radius_ratio = rr;
        best_p = p;
        best = cur;
      }
    }
  }
  if (at_best) *at_best = best;
  return best_p;
}

}  // namespace incise
