// CGAL shim: regularized 3-D alpha shapes behind the C API of alpha_shape_cgal.h.
#include "alpha_shape_cgal.h"

#include <CGAL/Alpha_shape_3.h>
#include <CGAL/Alpha_shape_cell_base_3.h>
#include <CGAL/Alpha_shape_vertex_base_3.h>
#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <limits>
#include <unordered_map>
#include <vector>

namespace {

typedef CGAL::Exact_predicates_inexact_constructions_kernel K;
typedef CGAL::Alpha_shape_vertex_base_3<K> Vb;
typedef CGAL::Alpha_shape_cell_base_3<K> Fb;
typedef CGAL::Triangulation_data_structure_3<Vb, Fb> Tds;
typedef CGAL::Delaunay_triangulation_3<K, Tds, CGAL::Fast_location> Delaunay;
typedef CGAL::Alpha_shape_3<Delaunay> Alpha_shape;
typedef K::Point_3 Point;

// CGAL's facet order follows handle addresses, which depend on the heap's
// history: number the vertices by position and sort the triangles (each
// rotated to start at its smallest index, which keeps its orientation) so the
// mesh depends on the points alone.
void canonicalise(std::vector<float> &verts, std::vector<uint32_t> &tris)
{
    size_t nv = verts.size() / 3;
    std::vector<uint32_t> order(nv), rank(nv);
    for (size_t i = 0; i < nv; i++) order[i] = (uint32_t)i;
    std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
        for (int k = 0; k < 3; k++)
            if (verts[3 * a + k] != verts[3 * b + k]) return verts[3 * a + k] < verts[3 * b + k];
        return a < b;
    });
    std::vector<float> sorted(verts.size());
    for (size_t i = 0; i < nv; i++) {
        rank[order[i]] = (uint32_t)i;
        for (int k = 0; k < 3; k++) sorted[3 * i + k] = verts[3 * order[i] + k];
    }
    verts.swap(sorted);
    size_t nt = tris.size() / 3;
    std::vector<std::array<uint32_t, 3>> t(nt);
    for (size_t i = 0; i < nt; i++) {
        uint32_t a = rank[tris[3 * i]], b = rank[tris[3 * i + 1]], c = rank[tris[3 * i + 2]];
        if (b < a && b < c) t[i] = {b, c, a};
        else if (c < a && c < b) t[i] = {c, a, b};
        else t[i] = {a, b, c};
    }
    std::sort(t.begin(), t.end());
    for (size_t i = 0; i < nt; i++)
        for (int k = 0; k < 3; k++) tris[3 * i + k] = t[i][k];
}

int extract(const Alpha_shape &as, sy_alpha_mesh *out)
{
    std::vector<Alpha_shape::Facet> facets;
    as.get_alpha_shape_facets(std::back_inserter(facets), Alpha_shape::REGULAR);
    std::unordered_map<const void *, uint32_t> index;
    std::vector<float> verts;
    std::vector<uint32_t> tris;
    tris.reserve(facets.size() * 3);
    for (Alpha_shape::Facet f : facets) {
        // Look at every facet from its exterior cell so all triangles share one orientation.
        if (as.classify(f.first) != Alpha_shape::EXTERIOR) f = as.mirror_facet(f);
        int idx[3] = {(f.second + 1) % 4, (f.second + 2) % 4, (f.second + 3) % 4};
        if (f.second % 2 == 0) std::swap(idx[0], idx[1]);
        for (int k = 0; k < 3; k++) {
            Alpha_shape::Vertex_handle v = f.first->vertex(idx[k]);
            auto it = index.find(&*v);
            if (it == index.end()) {
                it = index.emplace(&*v, (uint32_t)(verts.size() / 3)).first;
                const Point &p = v->point();
                verts.push_back((float)p.x());
                verts.push_back((float)p.y());
                verts.push_back((float)p.z());
            }
            tris.push_back(it->second);
        }
    }
    canonicalise(verts, tris);
    out->n_verts = verts.size() / 3;
    out->n_tris = tris.size() / 3;
    out->verts = (float *)malloc(verts.size() * sizeof(float) + 1);
    out->tris = (uint32_t *)malloc(tris.size() * sizeof(uint32_t) + 1);
    if (!out->verts || !out->tris) return -2;
    std::copy(verts.begin(), verts.end(), out->verts);
    std::copy(tris.begin(), tris.end(), out->tris);
    return 0;
}

} // namespace

extern "C" sy_code sy_alpha_shape_boundary(const float *pts, size_t n, double alpha_scale, sy_alpha_mesh *out,
                                           sy_error *err)
{
    *out = sy_alpha_mesh{};
    try {
        std::vector<Point> p;
        p.reserve(n);
        for (size_t i = 0; i < n; i++) p.emplace_back(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]);
        Alpha_shape as(p.begin(), p.end(), 0, Alpha_shape::REGULARIZED);
        if (as.dimension() < 3) {
            return sy_fail(err, SY_EINPUT, "alpha shape: points span %d dimensions", as.dimension());
        }
        if (alpha_scale > 0) {
            auto opt = as.find_optimal_alpha(1);
            if (opt == as.alpha_end()) {
                return sy_fail(err, SY_EINPUT, "alpha shape: no alpha gives one solid component");
            }
            out->alpha_min = *opt;
            out->alpha = alpha_scale * *opt;
        } else {
            out->alpha_min = 0;
            out->alpha = std::numeric_limits<double>::max();
        }
        as.set_alpha(out->alpha);
        if (extract(as, out)) {
            sy_alpha_mesh_free(out);
            return sy_fail(err, SY_EINTERNAL, "alpha shape: out of memory");
        }
        return SY_OK;
    } catch (const std::exception &e) {
        sy_alpha_mesh_free(out);
        return sy_fail(err, SY_EINTERNAL, "alpha shape: CGAL: %s", e.what());
    }
}

extern "C" void sy_alpha_mesh_free(sy_alpha_mesh *m)
{
    free(m->verts);
    free(m->tris);
    *m = sy_alpha_mesh{};
}
