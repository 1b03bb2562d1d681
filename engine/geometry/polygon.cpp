#include "geometry/polygon.h"

#include <algorithm>
#include <cmath>

namespace spangle {

namespace {

/** The corners in 2D, in the plane of the Newell normal, turning counter-clockwise; false when
 *  the polygon has no area to speak of. */
bool project(const Vec3* p, std::size_t n, std::vector<double>& x, std::vector<double>& y) {
    double nx = 0, ny = 0, nz = 0;
    for (std::size_t k = 0; k < n; ++k) {
        const Vec3 pa = p[k], pb = p[(k + 1) % n];
        const double a[3] = {pa.x, pa.y, pa.z}, b[3] = {pb.x, pb.y, pb.z};
        nx += (a[1] - b[1]) * (a[2] + b[2]);
        ny += (a[2] - b[2]) * (a[0] + b[0]);
        nz += (a[0] - b[0]) * (a[1] + b[1]);
    }
    const double ax = std::fabs(nx), ay = std::fabs(ny), az = std::fabs(nz);
    if (!(ax + ay + az > 0.0)) return false;
    // Drop the normal's largest axis; keep the orientation counter-clockwise.
    const int drop = ax >= ay && ax >= az ? 0 : (ay >= az ? 1 : 2);
    const double sign = (drop == 0 ? nx : drop == 1 ? ny : nz) > 0.0 ? 1.0 : -1.0;
    x.resize(n);
    y.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
        const double c[3] = {p[k].x, p[k].y, p[k].z};
        x[k] = c[(drop + 1) % 3];
        y[k] = sign * c[(drop + 2) % 3];
    }
    return true;
}

/** Ear clipping over a doubly linked ring. Only a reflex corner can lie inside an ear (and a
 *  convex corner stays convex as ears are cut), so the ear test looks only at the reflex
 *  corners, found through a uniform grid over the outline's bounds. */
class EarClipper {
public:
    EarClipper(const uint32_t* f, const std::vector<double>& x, const std::vector<double>& y)
        : f_(f), x_(x), y_(y), n_(x.size()), prev_(n_), next_(n_), reflex_(n_), alive_(n_, 1) {
        for (std::size_t k = 0; k < n_; ++k) {
            prev_[k] = (k + n_ - 1) % n_;
            next_[k] = (k + 1) % n_;
        }
        std::size_t reflex_count = 0;
        for (std::size_t k = 0; k < n_; ++k) {
            reflex_[k] = cross(prev_[k], k, next_[k]) <= 0.0 ? 1 : 0;
            reflex_count += reflex_[k];
        }
        min_x_ = *std::min_element(x.begin(), x.end());
        min_y_ = *std::min_element(y.begin(), y.end());
        const double w = *std::max_element(x.begin(), x.end()) - min_x_;
        const double h = *std::max_element(y.begin(), y.end()) - min_y_;
        cells_ = std::clamp<std::size_t>(
            static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(reflex_count)))), 1,
            1024);
        cell_w_ = w > 0.0 ? w / static_cast<double>(cells_) : 1.0;
        cell_h_ = h > 0.0 ? h / static_cast<double>(cells_) : 1.0;
        // The reflex corners by cell, compressed rows.
        start_.assign(cells_ * cells_ + 1, 0);
        for (std::size_t k = 0; k < n_; ++k)
            if (reflex_[k]) ++start_[cell_of(k) + 1];
        for (std::size_t c = 0; c < cells_ * cells_; ++c) start_[c + 1] += start_[c];
        in_cell_.resize(reflex_count);
        std::vector<std::size_t> fill(start_.begin(), start_.end() - 1);
        for (std::size_t k = 0; k < n_; ++k)
            if (reflex_[k]) in_cell_[fill[cell_of(k)]++] = k;
        // The reflex corners still reflex, as a list too: a large ear late in the clipping
        // spans most cells while few reflex corners are left.
        live_at_.assign(n_, 0);
        for (std::size_t k = 0; k < n_; ++k)
            if (reflex_[k]) {
                live_at_[k] = live_.size();
                live_.push_back(k);
            }
    }

    void run(std::vector<uint32_t>& out) {
        std::size_t count = n_, b = 0, misses = 0;
        while (count > 3) {
            if (ear(b)) {
                const std::size_t a = prev_[b], c = next_[b];
                out.insert(out.end(), {f_[a], f_[b], f_[c]});
                next_[a] = c;
                prev_[c] = a;
                alive_[b] = 0;
                --count;
                for (const std::size_t v : {a, c})
                    if (reflex_[v] && cross(prev_[v], v, next_[v]) > 0.0) {
                        reflex_[v] = 0;
                        const std::size_t last = live_.back();
                        live_[live_at_[v]] = last;
                        live_at_[last] = live_at_[v];
                        live_.pop_back();
                    }
                // On past the next corner (as earcut does): cutting on from one corner would
                // fan from it, ears as large as the outline, each testing every cell.
                b = next_[c];
                misses = 0;
            } else if (++misses > count) {
                // No ear anywhere (an outline that crosses itself): the rest as a fan.
                for (std::size_t k = next_[b]; next_[k] != b; k = next_[k])
                    out.insert(out.end(), {f_[b], f_[k], f_[next_[k]]});
                return;
            } else {
                b = next_[b];
            }
        }
        out.insert(out.end(), {f_[prev_[b]], f_[b], f_[next_[b]]});
    }

private:
    double cross(std::size_t a, std::size_t b, std::size_t c) const {
        return (x_[b] - x_[a]) * (y_[c] - y_[a]) - (y_[b] - y_[a]) * (x_[c] - x_[a]);
    }
    std::size_t column(double x) const {
        const double t = std::floor((x - min_x_) / cell_w_);
        return static_cast<std::size_t>(std::clamp(t, 0.0, static_cast<double>(cells_ - 1)));
    }
    std::size_t row(double y) const {
        const double t = std::floor((y - min_y_) / cell_h_);
        return static_cast<std::size_t>(std::clamp(t, 0.0, static_cast<double>(cells_ - 1)));
    }
    std::size_t cell_of(std::size_t k) const { return row(y_[k]) * cells_ + column(x_[k]); }

    /** Whether the corner b with its two neighbours is an ear: it turns the outline's way and
     *  no reflex corner lies in (or on) its triangle. Corners at the ear's own places (a hole's
     *  bridge visits its two ends twice) do not block it. */
    bool ear(std::size_t b) const {
        const std::size_t a = prev_[b], c = next_[b];
        if (cross(a, b, c) <= 0.0) return false;
        const auto same = [&](std::size_t q, std::size_t r) {
            return f_[q] == f_[r] || (x_[q] == x_[r] && y_[q] == y_[r]);
        };
        const std::size_t c0 = column(std::min({x_[a], x_[b], x_[c]})),
                          c1 = column(std::max({x_[a], x_[b], x_[c]})),
                          r0 = row(std::min({y_[a], y_[b], y_[c]})),
                          r1 = row(std::max({y_[a], y_[b], y_[c]}));
        const auto blocks = [&](std::size_t q) {
            if (!alive_[q] || !reflex_[q] || same(q, a) || same(q, b) || same(q, c)) return false;
            return cross(a, b, q) >= 0.0 && cross(b, c, q) >= 0.0 && cross(c, a, q) >= 0.0;
        };
        if (live_.size() < (r1 - r0 + 1) * (c1 - c0 + 1)) {
            for (const std::size_t q : live_)
                if (blocks(q)) return false;
            return true;
        }
        for (std::size_t r = r0; r <= r1; ++r)
            for (std::size_t col = c0; col <= c1; ++col) {
                const std::size_t cell = r * cells_ + col;
                for (std::size_t i = start_[cell]; i < start_[cell + 1]; ++i)
                    if (blocks(in_cell_[i])) return false;
            }
        return true;
    }

    const uint32_t* f_;
    const std::vector<double>& x_;
    const std::vector<double>& y_;
    std::size_t n_;
    std::vector<std::size_t> prev_, next_;
    std::vector<unsigned char> reflex_, alive_;
    double min_x_ = 0, min_y_ = 0, cell_w_ = 1, cell_h_ = 1;
    std::size_t cells_ = 1;
    std::vector<std::size_t> start_, in_cell_;
    std::vector<std::size_t> live_, live_at_;  ///< the corners still reflex; each one's place
};

}  // namespace

void triangulate_polygon(const uint32_t* f, const Vec3* p, std::size_t n,
                         std::vector<uint32_t>& out) {
    if (n < 3) return;
    std::vector<double> x, y;
    bool convex = true;
    if (n > 3 && project(p, n, x, y)) {
        for (std::size_t k = 0; k < n && convex; ++k) {
            const std::size_t a = (k + n - 1) % n, c = (k + 1) % n;
            convex = (x[k] - x[a]) * (y[c] - y[a]) - (y[k] - y[a]) * (x[c] - x[a]) >= 0.0;
        }
    }
    if (convex) {
        // Also a polygon without area: a fan, as the readers always made.
        for (std::size_t k = 1; k + 1 < n; ++k) out.insert(out.end(), {f[0], f[k], f[k + 1]});
        return;
    }
    EarClipper(f, x, y).run(out);
}

void triangulate_faces(TriangleMesh& mesh, const std::vector<uint32_t>& faces,
                       const std::vector<std::size_t>& ends) {
    const std::size_t nv = mesh.vertex_count();
    std::vector<Vec3> p;
    std::size_t begin = 0;
    for (const std::size_t end : ends) {
        const uint32_t* f = &faces[begin];
        const std::size_t n = end - begin;
        begin = end;
        p.resize(n);
        for (std::size_t k = 0; k < n; ++k) p[k] = f[k] < nv ? mesh.position(f[k]) : Vec3(0.0f);
        triangulate_polygon(f, p.data(), n, mesh.indices);
    }
}

}  // namespace spangle
