/* Scanners: every pulse is a pure function of its index (pose, direction,
 * time) and of a counter-based RNG keyed by (seed, pulse), so pulses can be
 * traced in any order on any number of threads and the output, gathered in
 * chunk order, is always the same. */
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "scan.h"
#include "stages/core/parallel.h"
#include "stages/core/progress.h"
#include "stages/core/rng.h"
#include "stages/core/vec3.h"

#define PI 3.14159265358979323846
#define DEG (PI / 180)
#define MAX_SUBRAYS 16
#define CHUNK 2048

sy_scan_options sy_scan_options_for(sy_scanner_kind kind)
{
    sy_scan_options value_, *sc = &value_;
    memset(sc, 0, sizeof *sc);
    sc->kind = kind;
    sc->seed = 1;
    sc->positions = 4;
    sc->height = kind == SY_SCANNER_MOBILE ? 1.8 : 1.5;
    sc->step_deg = kind == SY_SCANNER_MOBILE ? 0.25 : 0.04;
    sc->speed = kind == SY_SCANNER_AIRBORNE ? 50.0 : 1.2;
    sc->rotation_hz = 20;
    sc->line_spacing = 10;
    sc->altitude = 80;
    sc->swath_deg = 40;
    sc->density = 20;
    sc->overlap = 0.2;
    sc->divergence_mrad = kind == SY_SCANNER_AIRBORNE ? 0.5 : 0.3;
    sc->subrays = 5;
    sc->noise = kind == SY_SCANNER_AIRBORNE ? 0.025 : kind == SY_SCANNER_MOBILE ? 0.015 : 0.005;
    sc->max_returns = 4;
    sc->separation = kind == SY_SCANNER_AIRBORNE ? 0.5 : 0.1;
    sc->max_range = kind == SY_SCANNER_AIRBORNE ? 1500 : 150;
    sc->pulse_rate = kind == SY_SCANNER_AIRBORNE ? 400e3 : 500e3;
    return value_;
}

sy_scan_options sy_scan_options_default(void) { return sy_scan_options_for(SY_SCANNER_TERRESTRIAL); }

sy_code sy_scan_options_check(const sy_scan_options *sc, sy_error *err)
{
    if (sc->max_returns < 1 || sc->max_returns > 15)
        return sy_fail(err, SY_EUSAGE, "scan: max_returns %d outside [1, 15]", sc->max_returns);
    if (sc->divergence_mrad > 0 && (sc->subrays < 1 || sc->subrays > MAX_SUBRAYS))
        return sy_fail(err, SY_EUSAGE, "scan: subrays %d outside [1, %d]", sc->subrays, MAX_SUBRAYS);
    switch (sc->kind) {
    case SY_SCANNER_TERRESTRIAL:
        if (sc->positions < 1 || sc->positions > 1000)
            return sy_fail(err, SY_EUSAGE, "scan: positions %d outside [1, 1000]", sc->positions);
        if (!(sc->step_deg > 0)) return sy_fail(err, SY_EUSAGE, "scan: step_deg %g must be positive", sc->step_deg);
        break;
    case SY_SCANNER_MOBILE:
        if (!(sc->step_deg > 0) || !(sc->rotation_hz > 0) || !(sc->speed > 0))
            return sy_fail(err, SY_EUSAGE, "scan: mobile step_deg %g, rotation_hz %g and speed %g must be positive",
                           sc->step_deg, sc->rotation_hz, sc->speed);
        break;
    case SY_SCANNER_AIRBORNE:
        if (!(sc->density > 0) || !(sc->altitude > 0) || !(sc->speed > 0))
            return sy_fail(err, SY_EUSAGE, "scan: airborne density %g, altitude %g and speed %g must be positive",
                           sc->density, sc->altitude, sc->speed);
        if (!(sc->swath_deg > 0 && sc->swath_deg < 170))
            return sy_fail(err, SY_EUSAGE, "scan: swath_deg %g outside (0, 170)", sc->swath_deg);
        if (!(sc->overlap >= 0 && sc->overlap <= 0.9))
            return sy_fail(err, SY_EUSAGE, "scan: overlap %g outside [0, 0.9]", sc->overlap);
        break;
    }
    return SY_OK;
}

const char *sy_scanner_kind_name(sy_scanner_kind kind)
{
    return kind == SY_SCANNER_MOBILE ? "mobile" : kind == SY_SCANNER_AIRBORNE ? "airborne" : "terrestrial";
}

/* ------------------------------------------------------------------ RNG */

static uint64_t mix64(uint64_t z) { return sy_mix64(z); }

/* Uniform in (0, 1]: draw number `stream` of pulse `pulse`. */
static double pulse_u01(uint64_t key, uint64_t pulse, uint64_t stream)
{
    uint64_t h = mix64(key ^ mix64(pulse * 0xD1B54A32D192ED03ull + stream));
    return (double)((h >> 11) + 1) * (1.0 / 9007199254740992.0);
}

static double pulse_gauss(uint64_t key, uint64_t pulse, uint64_t stream)
{
    double u1 = pulse_u01(key, pulse, stream), u2 = pulse_u01(key, pulse, stream + 1);
    return sqrt(-2 * log(u1)) * cos(2 * PI * u2);
}

/* ------------------------------------------------------------- geometry */

typedef struct {
    float xyz[3];
    double time;
    uint16_t intensity;
    uint8_t rn, nr, cls, wood;
    int32_t tree, species, branch;
} scan_return;

typedef struct {
    scan_return *r;
    size_t n, cap;
    int failed;
} chunk_out;

typedef struct {
    const sy_scene *scene;
    const sy_scan_options *sc;
    uint64_t key;
    double origin[3];
    size_t n_pulses;
    /* terrestrial */
    int n_st;
    double *st;        /* per station: x y z az0 el0 hstep vstep */
    size_t *st_cols, *st_rows, *st_start; /* st_start: n_st + 1 */
    /* mobile */
    double *path;      /* x y per vertex */
    double *cum;       /* cumulative length per vertex */
    size_t path_n;
    size_t per_profile;
    /* airborne */
    int strips;
    size_t lines, per_line;
    double y0, strip_gap, x0, line_gap, fly_z, half_swath;
    /* output */
    chunk_out *chunks;
    pthread_mutex_t lock;
    size_t done;
    sy_progress progress;
} scan_job;

static double ground_z(const sy_scene *s, double x, double y)
{
    return s->has_terrain ? sy_terrain_height(&s->terrain, x, y) : 0.0;
}

static int veg_empty(const sy_scene *s) { return !(s->veg_lo[0] <= s->veg_hi[0]); }

static void scene_centre(const sy_scene *s, double c[2])
{
    for (int k = 0; k < 2; k++)
        c[k] = veg_empty(s) ? 0.5 * (s->area_lo[k] + s->area_hi[k]) : 0.5 * (s->veg_lo[k] + s->veg_hi[k]);
}

static double auto_radius(const sy_scene *s)
{
    double half = 0;
    for (int k = 0; k < 2; k++)
        if (!veg_empty(s)) half = fmax(half, 0.5 * (s->veg_hi[k] - s->veg_lo[k]));
    return fmax(10.0, half + 5);
}

static double wrap_pi(double a)
{
    while (a > PI) a -= 2 * PI;
    while (a < -PI) a += 2 * PI;
    return a;
}

/* The angular window a station sweeps: the vegetation's bounding box (down
 * to the ground under it) seen from the station. Pulses outside it could only
 * hit open ground, so a tree scan spends its pulses where the tree is. */
static void station_window(const sy_scene *s, const double p[3], double *az0, double *az1, double *el0,
                           double *el1)
{
    int inside = veg_empty(s) || (p[0] >= s->veg_lo[0] && p[0] <= s->veg_hi[0] && p[1] >= s->veg_lo[1] &&
                                  p[1] <= s->veg_hi[1]);
    if (inside) {
        *az0 = -PI;
        *az1 = PI;
        *el0 = -60 * DEG;
        *el1 = 90 * DEG;
        return;
    }
    double c[2];
    scene_centre(s, c);
    double mid = atan2(c[1] - p[1], c[0] - p[0]);
    *az0 = *el0 = INFINITY;
    *az1 = *el1 = -INFINITY;
    double zlo = s->veg_lo[2];
    for (int k = 0; k < 4; k++) {
        double x = (k & 1) ? s->veg_hi[0] : s->veg_lo[0], y = (k & 2) ? s->veg_hi[1] : s->veg_lo[1];
        zlo = fmin(zlo, ground_z(s, x, y));
    }
    for (int k = 0; k < 8; k++) {
        double x = (k & 1) ? s->veg_hi[0] : s->veg_lo[0], y = (k & 2) ? s->veg_hi[1] : s->veg_lo[1];
        double z = (k & 4) ? s->veg_hi[2] : zlo;
        double az = wrap_pi(atan2(y - p[1], x - p[0]) - mid), el = atan2(z - p[2], hypot(x - p[0], y - p[1]));
        *az0 = fmin(*az0, az);
        *az1 = fmax(*az1, az);
        *el0 = fmin(*el0, el);
        *el1 = fmax(*el1, el);
    }
    *az0 += mid;
    *az1 += mid;
    *el1 = fmin(*el1, 90 * DEG);
}

static sy_code plan_terrestrial(scan_job *j, int *stations, sy_error *err)
{
    const sy_scan_options *sc = j->sc;
    double hstep = sc->step_deg * DEG, vstep = (sc->vstep_deg > 0 ? sc->vstep_deg : sc->step_deg) * DEG;
    j->n_st = *stations = sc->positions;
    j->st = sy_calloc((size_t)j->n_st, 7 * sizeof(double), err, "stations");
    j->st_cols = sy_calloc((size_t)j->n_st, sizeof(size_t), err, "stations");
    j->st_rows = sy_calloc((size_t)j->n_st, sizeof(size_t), err, "stations");
    j->st_start = sy_calloc((size_t)j->n_st + 1, sizeof(size_t), err, "stations");
    if (!j->st || !j->st_cols || !j->st_rows || !j->st_start) return SY_EINTERNAL;
    double c[2], radius = sc->radius > 0 ? sc->radius : auto_radius(j->scene);
    scene_centre(j->scene, c);
    double total = 0;
    for (int i = 0; i < j->n_st; i++) {
        double *st = j->st + 7 * i, a = 2 * PI * i / j->n_st;
        st[0] = c[0] + radius * cos(a);
        st[1] = c[1] + radius * sin(a);
        st[2] = ground_z(j->scene, st[0], st[1]) + sc->height;
        double az0, az1, el0, el1;
        station_window(j->scene, st, &az0, &az1, &el0, &el1);
        st[3] = az0;
        st[4] = el0;
        st[5] = hstep;
        st[6] = vstep;
        j->st_cols[i] = (size_t)floor((az1 - az0) / hstep) + 1;
        j->st_rows[i] = (size_t)floor((el1 - el0) / vstep) + 1;
        total += (double)j->st_cols[i] * j->st_rows[i];
        j->st_start[i + 1] = j->st_start[i] + j->st_cols[i] * j->st_rows[i];
    }
    if (total > 2e9) return sy_fail(err, SY_EUSAGE, "scan: %.3g pulses; use a larger --step", total);
    j->n_pulses = j->st_start[j->n_st];
    return SY_OK;
}

static void pulse_terrestrial(const scan_job *j, size_t i, double o[3], double d[3], double *time)
{
    int s = 0;
    while (s + 1 < j->n_st && j->st_start[s + 1] <= i) s++;
    const double *st = j->st + 7 * s;
    size_t local = i - j->st_start[s], col = local / j->st_rows[s], row = local % j->st_rows[s];
    double az = st[3] + col * st[5], el = st[4] + row * st[6];
    memcpy(o, st, 3 * sizeof(double));
    d[0] = cos(el) * cos(az);
    d[1] = cos(el) * sin(az);
    d[2] = sin(el);
    /* A minute to carry the instrument to each next station. */
    *time = (double)i / j->sc->pulse_rate + 60.0 * s;
}

static sy_code path_push(scan_job *j, size_t *cap, double x, double y, sy_error *err)
{
    if (j->path_n == *cap) {
        *cap = *cap ? 2 * *cap : 256;
        double *p = realloc(j->path, *cap * 2 * sizeof(double));
        if (!p) return sy_fail(err, SY_EINTERNAL, "out of memory for the scan path");
        j->path = p;
    }
    j->path[2 * j->path_n] = x;
    j->path[2 * j->path_n + 1] = y;
    j->path_n++;
    return SY_OK;
}

static sy_code plan_mobile(scan_job *j, int *passes, sy_error *err)
{
    const sy_scan_options *sc = j->sc;
    size_t cap = 0;
    const sy_scene *s = j->scene;
    *passes = 1;
    if (sc->path && sc->path_points >= 2) {
        for (size_t i = 0; i < sc->path_points; i++)
            if (path_push(j, &cap, sc->path[2 * i], sc->path[2 * i + 1], err)) return err->code;
    } else if (sc->lawnmower) {
        double sp = sc->line_spacing > 0 ? sc->line_spacing : 10;
        int lines = (int)ceil((s->area_hi[1] - s->area_lo[1]) / sp);
        if (lines < 1) lines = 1;
        if (lines > 10000) return sy_fail(err, SY_EUSAGE, "scan: --line-spacing %g is too small", sp);
        double x0 = s->area_lo[0] - 5, x1 = s->area_hi[0] + 5;
        for (int l = 0; l < lines; l++) {
            double y = s->area_lo[1] + (l + 0.5) * (s->area_hi[1] - s->area_lo[1]) / lines;
            if (path_push(j, &cap, l % 2 ? x1 : x0, y, err) || path_push(j, &cap, l % 2 ? x0 : x1, y, err))
                return err->code;
        }
        *passes = lines;
    } else {
        double c[2], r = sc->radius > 0 ? sc->radius : auto_radius(s);
        scene_centre(s, c);
        for (int k = 0; k <= 180; k++)
            if (path_push(j, &cap, c[0] + r * cos(2 * PI * k / 180), c[1] + r * sin(2 * PI * k / 180), err))
                return err->code;
    }
    j->cum = sy_calloc(j->path_n, sizeof(double), err, "scan path");
    if (!j->cum) return SY_EINTERNAL;
    for (size_t i = 1; i < j->path_n; i++)
        j->cum[i] = j->cum[i - 1] + hypot(j->path[2 * i] - j->path[2 * i - 2], j->path[2 * i + 1] - j->path[2 * i - 1]);
    double len = j->cum[j->path_n - 1];
    if (!(len > 0)) return sy_fail(err, SY_EUSAGE, "scan: the mobile path has zero length");
    j->per_profile = (size_t)floor(360.0 / sc->step_deg);
    double profiles = floor(len / sc->speed * sc->rotation_hz);
    if (profiles * j->per_profile > 2e9) return sy_fail(err, SY_EUSAGE, "scan: too many pulses; use a larger --step");
    j->n_pulses = (size_t)profiles * j->per_profile;
    return SY_OK;
}

static void pulse_mobile(const scan_job *j, size_t i, double o[3], double d[3], double *time)
{
    const sy_scan_options *sc = j->sc;
    size_t prof = i / j->per_profile, k = i % j->per_profile;
    double t = (prof + (double)k / j->per_profile) / sc->rotation_hz, s = t * sc->speed;
    size_t lo = 0, hi = j->path_n - 1;
    while (hi - lo > 1) {
        size_t mid = (lo + hi) / 2;
        if (j->cum[mid] <= s) lo = mid;
        else hi = mid;
    }
    double seg = j->cum[hi] - j->cum[lo], f = seg > 0 ? (s - j->cum[lo]) / seg : 0;
    double ax = j->path[2 * lo], ay = j->path[2 * lo + 1], bx = j->path[2 * hi], by = j->path[2 * hi + 1];
    o[0] = ax + f * (bx - ax);
    o[1] = ay + f * (by - ay);
    o[2] = ground_z(j->scene, o[0], o[1]) + sc->height;
    double tx = seg > 0 ? (bx - ax) / seg : 1, ty = seg > 0 ? (by - ay) / seg : 0;
    /* The profile plane is vertical and across the walking direction. */
    double phi = 2 * PI * k / j->per_profile;
    d[0] = sin(phi) * ty;
    d[1] = -sin(phi) * tx;
    d[2] = cos(phi);
    *time = t;
}

static sy_code plan_airborne(scan_job *j, int *strips, sy_error *err)
{
    const sy_scan_options *sc = j->sc;
    const sy_scene *s = j->scene;
    double ly = s->area_hi[1] - s->area_lo[1], lx = s->area_hi[0] - s->area_lo[0];
    if (!(lx > 0 && ly > 0)) return sy_fail(err, SY_EUSAGE, "scan: the scene has no survey area");
    double cx = 0.5 * (s->area_lo[0] + s->area_hi[0]), cy = 0.5 * (s->area_lo[1] + s->area_hi[1]);
    j->fly_z = ground_z(s, cx, cy) + sc->altitude;
    j->half_swath = 0.5 * sc->swath_deg * DEG;
    double w = 2 * sc->altitude * tan(j->half_swath);
    j->strip_gap = w * (1 - sc->overlap);
    j->strips = ly <= w ? 1 : (int)ceil((ly - w) / j->strip_gap) + 1;
    if (j->strips > 100000) return sy_fail(err, SY_EUSAGE, "scan: too many flight strips");
    j->y0 = cy - 0.5 * (j->strips - 1) * j->strip_gap;
    /* Overlapping strips add up: each flies density * gap / width, so the area
     * as a whole receives `density` pulses per m^2. */
    double strip_density = sc->density * j->strip_gap / w;
    j->per_line = (size_t)ceil(w * sqrt(strip_density));
    if (j->per_line < 1) j->per_line = 1;
    j->line_gap = (double)j->per_line / (strip_density * w);
    j->lines = (size_t)floor(lx / j->line_gap) + 1;
    j->x0 = s->area_lo[0] + 0.5 * (lx - (j->lines - 1) * j->line_gap);
    double total = (double)j->strips * j->lines * j->per_line;
    if (total > 2e9) return sy_fail(err, SY_EUSAGE, "scan: %.3g pulses; lower --density", total);
    j->n_pulses = (size_t)total;
    *strips = j->strips;
    return SY_OK;
}

static void pulse_airborne(const scan_job *j, size_t i, double o[3], double d[3], double *time)
{
    size_t per_strip = j->lines * j->per_line;
    size_t strip = i / per_strip, rem = i % per_strip, line = rem / j->per_line, k = rem % j->per_line;
    /* Strips alternate direction; each line sweeps the swath at equal angle steps. */
    size_t l = strip % 2 ? j->lines - 1 - line : line;
    double theta = -j->half_swath + (k + 0.5) * (2 * j->half_swath / j->per_line);
    o[0] = j->x0 + l * j->line_gap;
    o[1] = j->y0 + strip * j->strip_gap;
    o[2] = j->fly_z;
    d[0] = 0;
    d[1] = sin(theta);
    d[2] = -cos(theta);
    double line_time = j->line_gap / j->sc->speed;
    *time = strip * (j->lines * line_time + 120.0) + (line + (double)k / j->per_line) * line_time;
}

/* --------------------------------------------------------------- beam */

typedef struct {
    double t;
    uint32_t prim;
    int sub;
} sub_hit;

static double reflectance(const sy_prim *p)
{
    return p->material == SY_MAT_GROUND ? 0.3 : p->material == SY_MAT_LEAF ? 0.35 : 0.5;
}

static int push_return(chunk_out *out, const scan_return *r)
{
    if (out->n == out->cap) {
        size_t cap = out->cap ? 2 * out->cap : 4096;
        scan_return *q = realloc(out->r, cap * sizeof *q);
        if (!q) return 0;
        out->r = q;
        out->cap = cap;
    }
    out->r[out->n++] = *r;
    return 1;
}

static void trace_pulse(const scan_job *j, size_t i, chunk_out *out)
{
    const sy_scan_options *sc = j->sc;
    const sy_bvh *bvh = &j->scene->bvh;
    const sy_prim *prims = j->scene->prims.p;
    double o[3], d[3], time;
    if (sc->kind == SY_SCANNER_TERRESTRIAL) pulse_terrestrial(j, i, o, d, &time);
    else if (sc->kind == SY_SCANNER_MOBILE) pulse_mobile(j, i, o, d, &time);
    else pulse_airborne(j, i, o, d, &time);

    int k_rays = sc->divergence_mrad > 0 && sc->subrays > 1 ? sc->subrays : 1;
    double dirs[MAX_SUBRAYS][3];
    memcpy(dirs[0], d, sizeof dirs[0]);
    if (k_rays > 1) {
        double u[3], v[3];
        sy_v3_basis_across(d, u, v);
        double half = 0.5e-3 * sc->divergence_mrad, phase = 2 * PI * pulse_u01(j->key, i, 0);
        /* A golden-angle spiral fills the footprint disc evenly. */
        for (int k = 1; k < k_rays; k++) {
            double r = tan(half) * sqrt((k - 0.5) / (k_rays - 1)), a = phase + 2.39996322972865332 * k;
            double len = 0;
            for (int c = 0; c < 3; c++) {
                dirs[k][c] = d[c] + r * (cos(a) * u[c] + sin(a) * v[c]);
                len += dirs[k][c] * dirs[k][c];
            }
            len = sqrt(len);
            for (int c = 0; c < 3; c++) dirs[k][c] /= len;
        }
    }
    sub_hit hits[MAX_SUBRAYS];
    int n_hits = 0;
    for (int k = 0; k < k_rays; k++) {
        sy_hit h;
        /* Sub-rays of one beam mostly hit what the previous one did: testing
         * that surface first gives the traversal a tight bound. nextafter keeps
         * it findable again, so the result equals an unbounded search. */
        double bound = sc->max_range, t;
        if (n_hits && sy_prim_intersect(&prims[hits[0].prim], o, dirs[k], SY_SCAN_TMIN, bound, &t))
            bound = nextafter(t, INFINITY);
        if (sy_bvh_closest(bvh, o, dirs[k], bound, sy_prim_ray_hit, prims, &h)) {
            /* Insertion by range keeps the list sorted. */
            int at = n_hits++;
            while (at > 0 && hits[at - 1].t > h.t) {
                hits[at] = hits[at - 1];
                at--;
            }
            hits[at] = (sub_hit){h.t, h.prim, k};
        }
    }
    if (!n_hits) return;
    /* Cluster sub-ray hits closer than the separation into one echo. */
    int start[MAX_SUBRAYS + 1], n_cl = 0;
    for (int h = 0; h < n_hits; h++)
        if (h == 0 || hits[h].t - hits[h - 1].t > sc->separation) start[n_cl++] = h;
    start[n_cl] = n_hits;
    int max_ret = sc->max_returns;
    int kept = n_cl < max_ret ? n_cl : max_ret;
    for (int r = 0; r < kept; r++) {
        /* Past the limit the first max-1 echoes and the last one survive. */
        int cl = (r == kept - 1) ? n_cl - 1 : r;
        int rep = start[cl];
        double energy = 0;
        for (int h = start[cl]; h < start[cl + 1]; h++) {
            if (hits[h].sub < hits[rep].sub) rep = h;
            const sy_prim *p = &prims[hits[h].prim];
            const double *dd = dirs[hits[h].sub];
            double x[3] = {o[0] + hits[h].t * dd[0], o[1] + hits[h].t * dd[1], o[2] + hits[h].t * dd[2]}, n[3];
            sy_prim_normal(p, x, n);
            energy += reflectance(p) * fabs(n[0] * dd[0] + n[1] * dd[1] + n[2] * dd[2]) / k_rays;
        }
        const sy_prim *p = &prims[hits[rep].prim];
        const double *dd = dirs[hits[rep].sub];
        double range = hits[rep].t + (sc->noise > 0 ? sc->noise * pulse_gauss(j->key, i, 16 + 2 * (uint64_t)r) : 0);
        scan_return ret;
        for (int c = 0; c < 3; c++) ret.xyz[c] = (float)(o[c] + range * dd[c] - j->origin[c]);
        ret.time = time;
        ret.intensity = (uint16_t)lround(fmin(1.0, energy) * 65535);
        ret.rn = (uint8_t)(r + 1);
        ret.nr = (uint8_t)kept;
        int ground = p->material == SY_MAT_GROUND;
        ret.cls = ground ? 2 : p->understory ? 4 : 5;
        ret.wood = p->material == SY_MAT_WOOD && !p->understory;
        ret.tree = p->tree_id;
        ret.species = p->species_id;
        ret.branch = p->branch_id;
        if (!push_return(out, &ret)) {
            out->failed = 1;
            return;
        }
    }
}

static void scan_chunk(void *ctx, size_t begin, size_t end, size_t chunk)
{
    scan_job *j = ctx;
    chunk_out *out = &j->chunks[chunk];
    for (size_t i = begin; i < end && !out->failed; i++) trace_pulse(j, i, out);
    pthread_mutex_lock(&j->lock);
    j->done += end - begin;
    sy_progress_update(&j->progress, j->done);
    pthread_mutex_unlock(&j->lock);
}

static sy_code fill_cloud(const scan_job *j, size_t n_chunks, size_t total, sy_cloud *c, sy_scan_stats *st,
                          sy_error *err)
{
    if (sy_cloud_init(c, total, err)) return err->code;
    memcpy(c->origin, j->origin, sizeof c->origin);
    double *tree = NULL, *species = NULL, *wood = NULL, *branch = NULL;
    if (sy_cloud_add_intensity(c, err) || sy_cloud_add_returns(c, err) || sy_cloud_add_classification(c, err) ||
        sy_cloud_add_gps_time(c, err) || !(tree = sy_cloud_add_attr(c, "treeID", err)) ||
        !(species = sy_cloud_add_attr(c, "speciesID", err)) || !(wood = sy_cloud_add_attr(c, "isWood", err)) ||
        !(branch = sy_cloud_add_attr(c, "branchID", err))) {
        sy_cloud_free(c);
        return SY_EINTERNAL;
    }
    /* A cap keeps an even spread of the returns in pulse order (the k-th kept
     * is return floor(k * all / total)), so a capped scan still covers every
     * station and the whole tree, only sparser: the first N returns of a
     * terrestrial sweep would be a wedge of the first station's view. */
    size_t all = 0;
    for (size_t ch = 0; ch < n_chunks; ch++) all += j->chunks[ch].n;
    size_t at = 0, seen = 0;
    for (size_t ch = 0; ch < n_chunks && at < total; ch++)
        for (size_t k = 0; k < j->chunks[ch].n && at < total; k++, seen++) {
            if (seen != (size_t)((unsigned long long)at * all / total)) continue;
            const scan_return *r = &j->chunks[ch].r[k];
            memcpy(c->xyz + 3 * at, r->xyz, sizeof r->xyz);
            c->intensity[at] = r->intensity;
            c->return_number[at] = r->rn;
            c->num_returns[at] = r->nr;
            c->classification[at] = r->cls;
            c->gps_time[at] = r->time;
            tree[at] = r->tree;
            species[at] = r->species;
            wood[at] = r->wood;
            branch[at] = r->branch;
            if (r->cls == 2) st->ground++;
            else if (r->cls == 4) st->understory++;
            else if (r->wood) st->wood++;
            else st->leaf++;
            at++;
        }
    return SY_OK;
}

static void free_job(scan_job *j, size_t n_chunks)
{
    free(j->st);
    free(j->st_cols);
    free(j->st_rows);
    free(j->st_start);
    free(j->path);
    free(j->cum);
    if (j->chunks)
        for (size_t i = 0; i < n_chunks; i++) free(j->chunks[i].r);
    free(j->chunks);
    pthread_mutex_destroy(&j->lock);
}

sy_code sy_scan(const sy_scene *s, const sy_scan_options *sc, sy_cloud *out, sy_scan_stats *stats, sy_error *err)
{
    memset(out, 0, sizeof *out);
    sy_code checked = sy_scan_options_check(sc, err);
    if (checked) return checked;
    sy_scan_stats st = {0};
    double t0 = sy_now();
    scan_job j;
    memset(&j, 0, sizeof j);
    pthread_mutex_init(&j.lock, NULL);
    j.scene = s;
    j.sc = sc;
    j.key = mix64(sc->seed ^ 0x5343414E4E4552ull);
    /* Points are stored as float offsets from a whole-metre origin near the scene. */
    double c[2];
    scene_centre(s, c);
    j.origin[0] = floor(c[0]);
    j.origin[1] = floor(c[1]);
    j.origin[2] = floor(ground_z(s, c[0], c[1]));
    sy_code rc;
    if (!(sc->max_range > 0)) rc = sy_fail(err, SY_EUSAGE, "scan: --max-range must be positive");
    else if (!(sc->noise >= 0) || !(sc->divergence_mrad >= 0) || !(sc->separation >= 0))
        rc = sy_fail(err, SY_EUSAGE, "scan: --noise, --divergence and --separation must not be negative");
    else if (sc->kind == SY_SCANNER_TERRESTRIAL) rc = plan_terrestrial(&j, &st.stations, err);
    else if (sc->kind == SY_SCANNER_MOBILE) rc = plan_mobile(&j, &st.stations, err);
    else rc = plan_airborne(&j, &st.stations, err);
    size_t n_chunks = (j.n_pulses + CHUNK - 1) / CHUNK;
    if (!rc) {
        j.chunks = sy_calloc(n_chunks ? n_chunks : 1, sizeof(chunk_out), err, "scan chunks");
        if (!j.chunks) rc = SY_EINTERNAL;
    }
    if (!rc) {
        sy_progress_begin(&j.progress, "scan", j.n_pulses);
        sy_parallel_for(j.n_pulses, CHUNK, scan_chunk, &j);
        sy_progress_end(&j.progress);
        size_t total = 0;
        for (size_t i = 0; i < n_chunks; i++) {
            if (j.chunks[i].failed) rc = sy_fail(err, SY_EINTERNAL, "scan: out of memory for points");
            total += j.chunks[i].n;
        }
        if (sc->max_points && total > sc->max_points) total = sc->max_points;
        if (!rc) rc = fill_cloud(&j, n_chunks, total, out, &st, err);
        st.pulses = j.n_pulses;
        st.points = total;
    }
    free_job(&j, n_chunks);
    st.seconds = sy_now() - t0;
    if (stats) *stats = st;
    return rc;
}

/* Keeps the points within radius of centre (any label) or, with tree_id >= 1,
 * that tree's points and the unlabelled (ground, understory) ones within
 * radius; recounts stats. */
static sy_code keep_points(sy_cloud *c, int tree_id, const double centre[2], double radius, sy_scan_stats *stats,
                           sy_error *err)
{
    if (!(radius > 0)) return sy_fail(err, SY_EUSAGE, "scan: the clip radius must be positive");
    uint8_t *keep = sy_calloc(c->n ? c->n : 1, 1, err, "clip mask");
    if (!keep) return err->code;
    const double *wood = sy_cloud_attr(c, "isWood"), *tree = sy_cloud_attr(c, "treeID");
    sy_scan_stats counted = stats ? *stats : (sy_scan_stats){0};
    counted.points = counted.wood = counted.leaf = counted.ground = counted.understory = 0;
    for (size_t i = 0; i < c->n; i++) {
        double dx = c->origin[0] + c->xyz[3 * i] - centre[0], dy = c->origin[1] + c->xyz[3 * i + 1] - centre[1];
        int near = dx * dx + dy * dy <= radius * radius;
        int label = tree ? (int)tree[i] : 0;
        keep[i] = tree_id >= 1 ? label == tree_id || (label == 0 && near) : near;
        if (!keep[i]) continue;
        counted.points++;
        uint8_t cls = c->classification ? c->classification[i] : 5;
        if (cls == 2) counted.ground++;
        else if (cls == 4) counted.understory++;
        else if (wood && wood[i] > 0.5) counted.wood++;
        else counted.leaf++;
    }
    sy_code rc = sy_cloud_filter(c, keep, err);
    free(keep);
    if (!rc && stats) *stats = counted;
    return rc;
}

sy_code sy_scan_clip_cylinder(sy_cloud *c, const double centre[2], double radius, sy_scan_stats *stats, sy_error *err)
{
    return keep_points(c, 0, centre, radius, stats, err);
}

sy_code sy_scan_isolate_tree(sy_cloud *c, int tree_id, const double centre[2], double radius, sy_scan_stats *stats,
                             sy_error *err)
{
    if (tree_id < 1) return sy_fail(err, SY_EUSAGE, "scan: no tree to isolate");
    return keep_points(c, tree_id, centre, radius, stats, err);
}
