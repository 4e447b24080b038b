/* Occluded stems of excurrent crowns. A dense conifer whose foliage reaches
 * the ground shows a terrestrial scanner only the outer shell of its crown and
 * hardly any stem. The shortest-path tree then runs along the shell, level
 * sets split into arcs, and the longest chain - the "trunk" - spirals up the
 * cone. The evidence that does exist is the crown itself: for an excurrent
 * (cone-shaped) crown the centroids of horizontal slabs lie on a near-vertical
 * line, the stem. This follows the occluded-stem treatment of conifer QSMs
 * (Hackenberg et al. 2015, SimpleTree: the stem axis from the crown's slab
 * centroids where the stem is not seen; Raumonen et al. 2013 for circle fits
 * where it is): when the trunk chain wanders far from that axis while the
 * centroids stay on it, the stem is rebuilt on the axis, its limbs grow from
 * it into the crown's returns by space colonisation (colonize.c), and its radius comes
 * from circle fits to the few stem returns there are (checked by residual,
 * arc coverage, centring on the axis and taper), the pipe-model allometry
 * carrying it to breast height.
 *
 * Decurrent leaf-on crowns hide their limbs the same way: the chains follow
 * the foliage shell, down one limb's side and up the next. When the trunk
 * chain meanders and the crown's returns are foliage, the trunk is kept to
 * its crown base and the crown above it regrown by the same colonisation
 * (sy_regrow_meandering_crown, docs/skeleton.md step 8c). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "skeleton_internal.h"
#include "stages/core/kdtree.h"
#include "stages/core/sort.h"

#define STEM_SLABS 32
#define STEM_TWO_PI 6.28318530717958647692
/* The trunk chain is off the stem when it strays this share of the median
 * crown radius from the axis (a real trunk stays within its own radius) ...
 * and at least this share of the height. They were 0.35 and 5 % while the
 * conifers' opaque needle cards made the chain stray 2.2 m; seen through
 * (leaf_fill), the simulated balsam fir's level sets fill the cone, its
 * skeleton is one 32-node chain 0.55 m off the axis (0.30 crown radii, 3.9 %
 * of the height) and its DBH 0.59 m for 0.38 m. None of the nine real scans
 * passes the other tests. */
#define STEM_EXCURSION_SHARE 0.25
#define STEM_EXCURSION_HEIGHT 0.03
/* Slab centroids on a line: their RMS distance from it below this share of the crown radius. */
#define STEM_AXIS_RMS_SHARE 0.35
/* Excurrent: the upper third's crown radius below this share of the lower half's. */
#define STEM_EXCURRENT_SHARE 0.8
/* A domed crown: above its widest slab, the mean radius at least this share
 * of the widest (cones 0.60-0.63, domes 0.70-0.77); its stem stops at the
 * highest slab within STEM_FORK_SHARE of the widest, kept within
 * STEM_FORK_MIN-STEM_FORK_MAX of the height. */
#define STEM_DOME_SHARE 0.69
#define STEM_FORK_SHARE 0.9
#define STEM_FORK_MIN 0.25
#define STEM_FORK_MAX 0.5
/* The stem is hidden only where the crown reaches the ground: the lowest
 * slabs' crown radius at least this share of the median. Below a crown that
 * starts higher up the scanner sees the bole, the shortest paths start on
 * it, and a trunk chain that then strays among the limbs is a decurrent
 * crown's trunk dividing, not a stem lost in foliage (sassafras: 0.3-0.4 m
 * at the foot under a 3.9 m crown, rebuilt into a pole with spokes). */
#define STEM_FOOT_SHARE 0.5
/* Height-to-diameter ratio of an excurrent stem whose bark the scan never
 * shows. The slenderness coefficient of conifers runs from about 40 for
 * open-grown trees to 100 and more in dense stands; a crown that reaches the
 * ground (the case that hides the stem) is an open-grown tree, so the low end. */
#define STEM_SLENDERNESS 45.0
/* The limbs' growth step as a share of the crown radius (at least two
 * level-set widths), the colonisation's kill distance in steps, and a cap on
 * the nodes it may add (a 20 m crown at a 0.6 m step needs 2-4 thousand). */
#define STEM_LIMB_STEP 0.1
#define STEM_LIMB_KILL 2.0
#define STEM_LIMB_NODES 20000
/* The root is on the stem when it lies within this many times the slab
 * centroids' RMS scatter of their free line. */
#define STEM_ROOT_ON_AXIS 2.0
/* The trunk is kept up to its crown base: the last node before the chain's
 * path exceeds this many times the straight distance, or a step rises less
 * than half its length. Both are measured from the node above the root
 * (base_above_root): the root is the lowest return, which can lie off the
 * stem (the palm sample's, 0.9 m to the side, made its first step rise 0.47
 * of its 1.0 m and put the crown base at the ground, so the whole palm was
 * regrown as a crown). */
#define CROWN_BASE_PATH 1.15
/* A crown of foliage: over height slabs of its upper 60 %, the median of
 * (median / 95th percentile) of the returns' distance from the slab
 * centroid exceeds this. A filled disc gives 0.73, a shell more; returns on
 * limbs crowd the middle (the nine real scans: 0.44-0.58; the simulated
 * leaf-on crowns: 0.66-0.82). */
#define CROWN_FOLIAGE_RATIO 0.62
/* No stem in the scan: the lowest return this share of the tree's height
 * (and at least 1 m) above the ground. An airborne scan sees a crown from
 * above: the simulated airborne aspen's lowest return stands 8.6 m up its
 * 13.6 m, the palm's 9.6 of 11.5, the beech's 10.3 of 24.7 (the fir's
 * skirt comes within 0.4 m of the ground; its spacing gives it away). A
 * terrestrial scan's lowest return is the foot, within the ground filter's
 * 0.1-0.3 m. */
#define UNSEEN_STEM_GAP 0.15
/* A scan this coarse (point spacing, metres) resolves no stem or limb: its
 * level sets are 4 spacings wide, 1.2 m and more, and its chains run over
 * the crown's surface (the simulated airborne fir, 0.34 m: a trunk that
 * crooks through the crown 3.9 m off its axis). Its tree is drawn as an
 * unseen stem's. AHN3's airborne Delft tree (0.22 m) still shows its bole
 * and keeps its own skeleton (drawn as an unseen stem at a 0.2 m bound, its
 * crown width went from -9.5 % to -14.3 % at the same IoU, and its limbs
 * stood off a pole like crossarms). Terrestrial scans have 0.01-0.09 m. */
#define UNSEEN_SPACING 0.3
/* Between 0.15 m and that, a scan is as coarse as an airborne one but may
 * still show a bole (AHN3's Delft tree, 0.22 m: 14 of the 133 returns in the
 * lowest 15 % of its height lie near the crown's axis). Where the crown
 * comes lower than the gap above, the stem counts as seen only with at
 * least 3 such returns, and more than 2 % of that band's. Else it is unseen:
 * the simulated airborne Norway spruce (0.244 m, its skirt 0.13 m up, 0 of
 * 261) grew its trunk from the skirt's edge, leaning 8 m across the crown,
 * and the London plane of seed 2 (0.266 m, 3.5 m up under a 24.3 m top, 1
 * return in the band) a trunk from its lowest limb. Near: within 15 % of
 * the returns' median distance from the axis, at least 0.5 m. Terrestrial
 * scans (0.01-0.09 m) never come here; their occluded stems are
 * sy_rebuild_occluded_stem's. */
#define UNSEEN_SKIRT_SPACING 0.15
#define UNSEEN_LOW_BAND 0.15
#define UNSEEN_BOLE_NEAR 0.15
#define UNSEEN_BOLE_NEAR_MIN 0.5
#define UNSEEN_BOLE_SHARE 0.02
#define UNSEEN_BOLE_MIN 3
/* An unseen stem's limbs grow from its fork in steps of this share of the
 * crown radius. The simulated airborne black oak, willow and palm (domes)
 * against their true trees, IoU: 0.640 / 0.625 / 0.473 at 0.1, 0.632 /
 * 0.638 / 0.479 at 0.2, 0.653 / 0.643 / 0.449 at 0.3. The occluded stem's
 * max(2 level sets, 0.1 radius) gave 0.617 / 0.614 / 0.406 (limbs then
 * grew from every trunk node), and 0.5 left the oak's top unreached. */
#define UNSEEN_LIMB_STEP 0.2
/* Height slabs over an unseen stem's crown, each needing this many returns. */
#define UNSEEN_SLABS 8
#define UNSEEN_SLAB_MIN 5

static double median_of(double *v, size_t k)
{
    if (!k) return 0;
    qsort(v, k, sizeof *v, sy_cmp_double);
    return k % 2 ? v[k / 2] : 0.5 * (v[k / 2 - 1] + v[k / 2]);
}

/* Stem circle fits: slabs near the base, the points within the inner band
 * around the axis. A fit stands only when its points are a stem, not a ring
 * of branch bases: enough inliers, most of the band's points on it, a
 * residual small against the radius, centred on the axis, an arc of at least
 * a third of the circle, and no wider than a fit below it (stems taper). */
static void measure_stem(const float *xyz, size_t n, double z0, double H, const double root[2], const double ax[2],
                         double band, double spacing, sy_stem_info *info)
{
    double *xy = malloc((n ? n : 1) * 2 * sizeof *xy), *ang = malloc((n ? n : 1) * sizeof *ang);
    if (!xy || !ang) goto done;
    double tol = fmax(0.5 * spacing, 0.01), slab = 0.25, best_r = 0, best_z = 0, best_rms = 0;
    double lowest_r = INFINITY, best_c[2] = {0, 0};
    size_t best_in = 0;
    double top = z0 + fmin(0.3 * H, 4.0);
    for (double zc = z0 + slab / 2; zc <= top; zc += slab / 2) {
        size_t k = 0;
        double cxa = root[0] + ax[0] * (zc - z0), cya = root[1] + ax[1] * (zc - z0);
        for (size_t i = 0; i < n; i++) {
            const float *p = xyz + 3 * i;
            if (fabs(p[2] - zc) > slab / 2) continue;
            if (hypot(p[0] - cxa, p[1] - cya) > band) continue;
            xy[2 * k] = p[0];
            xy[2 * k + 1] = p[1];
            k++;
        }
        double c[2], r, rms;
        if (k < 6 || sy_fit_circle(xy, k, tol, 7, c, &r, &rms) != 0) continue;
        size_t in = 0;
        for (size_t j = 0; j < k; j++) {
            double dx = xy[2 * j] - c[0], dy = xy[2 * j + 1] - c[1];
            if (fabs(hypot(dx, dy) - r) <= tol) ang[in++] = atan2(dy, dx);
        }
        if (in < 6 || (double)in < 0.6 * (double)k || r >= band || rms > 0.3 * r) continue;
        if (hypot(c[0] - cxa, c[1] - cya) > fmax(0.5 * r, 0.1)) continue;
        qsort(ang, in, sizeof *ang, sy_cmp_double);
        double gap = ang[0] + STEM_TWO_PI - ang[in - 1];
        for (size_t j = 1; j < in; j++) gap = fmax(gap, ang[j] - ang[j - 1]);
        if (gap > STEM_TWO_PI * 2.0 / 3.0) continue;
        if (r > 1.3 * lowest_r) continue; /* wider than the stem below: branch bases */
        lowest_r = fmin(lowest_r, r);
        if (in > best_in) {
            best_in = in;
            best_r = r;
            best_z = zc;
            best_rms = rms;
            best_c[0] = c[0];
            best_c[1] = c[1];
        }
    }
    if (best_in) {
        info->measured_r = best_r;
        info->measured_z = best_z;
        info->measured_rms = best_rms;
    } else {
        goto done; /* no stem circle: no centre to measure the few returns higher up on */
    }
    /* Higher up a dense crown lets through a few stem returns, too few for a
     * free circle but enough on a known centre: the innermost run of three or
     * more at one distance, narrower than any fit below (taper), is the stem
     * there: with the base fit it gives the taper to breast height past the
     * butt swell. */
    double *d = ang;
    for (double zc = best_z + 0.75; zc <= top; zc += 0.25) {
        double cxa = best_c[0] + ax[0] * (zc - best_z), cya = best_c[1] + ax[1] * (zc - best_z);
        size_t k = 0;
        for (size_t i = 0; i < n; i++) {
            const float *p = xyz + 3 * i;
            if (fabs(p[2] - zc) > 0.5) continue;
            double di = hypot(p[0] - cxa, p[1] - cya);
            if (di < best_r) d[k++] = di;
        }
        if (k < 3) continue;
        qsort(d, k, sizeof *d, sy_cmp_double);
        for (size_t j = 0; j + 2 < k; j++)
            if (d[j + 2] - d[j] <= tol && d[j] > 0.3 * best_r) {
                info->upper_r = d[j + 1];
                info->upper_z = zc;
                break;
            }
        if (info->upper_r > 0) break;
    }
done:
    free(xy);
    free(ang);
}

/* Replaces s by the M nodes at cpos whose parents are cpar (node 0 the
 * root, -1; every other node reaches it); every point joins its nearest node
 * (point_node remapped). s comes back breadth-first with support, radii 1
 * and branch ids to reassign. */
static sy_code adopt_tree(sy_skeleton *s, const float *cpos, const int32_t *cpar, size_t M, const float *xyz, size_t n,
                          int32_t *point_node, const uint8_t *wood, sy_error *err)
{
    int32_t *first = NULL, *next = NULL, *order = NULL, *final = NULL;
    uint32_t *label = NULL;
    sy_skeleton out = {0};
    sy_kdtree kd = {0};
    sy_code rc = SY_OK;
    first = malloc(M * sizeof *first);
    next = malloc(M * sizeof *next);
    order = malloc(M * sizeof *order);
    final = malloc(M * sizeof *final);
    label = calloc(M, sizeof *label);
    if (!first || !next || !order || !final || !label) {
        rc = sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
        goto done;
    }
    for (size_t v = 0; v < M; v++) first[v] = next[v] = -1;
    for (size_t v = M; v-- > 1;) {
        next[v] = first[cpar[v]];
        first[cpar[v]] = (int32_t)v;
    }
    size_t head = 0, tail = 0;
    order[tail++] = 0;
    while (head < tail) {
        int32_t u = order[head++];
        for (int32_t c = first[u]; c >= 0; c = next[c]) order[tail++] = c;
    }
    if ((rc = sy_skeleton_init(&out, M, err))) goto done;
    memcpy(out.origin, s->origin, sizeof out.origin);
    for (size_t t = 0; t < M; t++) final[order[t]] = (int32_t)t;
    for (size_t t = 0; t < M; t++) {
        int32_t u = order[t];
        memcpy(out.pos + 3 * t, cpos + 3 * (size_t)u, 3 * sizeof *cpos);
        out.parent[t] = t ? final[cpar[u]] : -1;
        out.radius[t] = 1;
    }
    out.support_start = calloc(M + 1, sizeof *out.support_start);
    out.support = calloc(n ? n : 1, sizeof *out.support);
    if (!out.support_start || !out.support || (rc = sy_kdtree_build(&kd, out.pos, M, err))) {
        if (!rc) rc = sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
        goto done;
    }
    sy_kdtree_relabel(&kd, label); /* all 0: the nearest node of any label but 1 */
    for (size_t i = 0; i < n; i++) {
        double d2 = INFINITY;
        uint32_t j = 0;
        sy_kdtree_nearest_foreign(&kd, xyz + 3 * i, 1, &d2, &j);
        point_node[i] = (int32_t)j;
        if (!wood || wood[i]) out.support_start[j + 1]++;
    }
    for (size_t t = 0; t < M; t++) out.support_start[t + 1] += out.support_start[t];
    for (size_t t = 0; t < M; t++) order[t] = (int32_t)out.support_start[t];
    for (size_t i = 0; i < n; i++)
        if (!wood || wood[i]) out.support[order[point_node[i]]++] = (uint32_t)i;
    sy_skeleton_free(s);
    *s = out;
    memset(&out, 0, sizeof out);
done:
    sy_skeleton_free(&out);
    sy_kdtree_free(&kd);
    free(first);
    free(next);
    free(order);
    free(final);
    free(label);
    return rc;
}

/* Replaces s by a chain of K trunk nodes (root first) and the limbs that
 * space colonisation (colonize.c) grows from them, from node `sprout` up
 * (below it a bare bole; sprout >= K: the trunk alone), into the returns
 * above height z_from, step
 * `grow`, kill distance STEM_LIMB_KILL steps (adopt_tree; every point joins
 * its nearest node). */
static sy_code regrow_from_trunk(sy_skeleton *s, const float *trunk, size_t K, size_t sprout, const float *xyz,
                                 size_t n, double z_from, int32_t *point_node, const uint8_t *wood, double grow,
                                 sy_error *err)
{
    float *cpos = NULL, *all = NULL, *attract = NULL;
    int32_t *cpar = NULL, *apar = NULL;
    size_t M = 0, na = 0;
    sy_code rc = SY_OK;
    if (sprout >= K) {
        sprout = K; /* the trunk alone */
    } else if (!(attract = malloc((n ? n : 1) * 3 * sizeof *attract))) {
        return sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
    } else {
        for (size_t i = 0; i < n; i++)
            if (xyz[3 * i + 2] > z_from) memcpy(attract + 3 * na++, xyz + 3 * i, 3 * sizeof *attract);
        rc = sy_colonize(trunk + 3 * sprout, K - sprout, attract, na, grow, STEM_LIMB_KILL * grow,
                         K - sprout + STEM_LIMB_NODES, &cpos, &cpar, &M, err);
        free(attract);
    }
    if (!rc) {
        /* The bole's nodes first, then the colonised ones (the sprouting
         * trunk nodes lead them, in order). */
        all = malloc((sprout + M) * 3 * sizeof *all);
        apar = malloc((sprout + M) * sizeof *apar);
        if (!all || !apar) rc = sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
    }
    if (!rc) {
        memcpy(all, trunk, sprout * 3 * sizeof *all);
        if (M) memcpy(all + 3 * sprout, cpos, M * 3 * sizeof *all);
        for (size_t t = 0; t < sprout + M; t++)
            apar[t] = t < K ? (int32_t)t - 1 : cpar[t - sprout] + (int32_t)sprout;
        rc = adopt_tree(s, all, apar, sprout + M, xyz, n, point_node, wood, err);
    }
    free(cpos), free(cpar), free(all), free(apar);
    return rc;
}

sy_code sy_rebuild_occluded_stem(sy_skeleton *s, const float *xyz, size_t n, int32_t *point_node,
                                 const uint8_t *wood, double w, double spacing, int fork_domes, sy_stem_info *info,
                                 sy_error *err)
{
    memset(info, 0, sizeof *info);
    size_t m = s->n;
    if (m < 4 || n < 100) return SY_OK;
    /* The slabs span the crown to its top but one return in 2,000: the
     * highest returns, a lone leaf tuft or the top a preprocessed file kept,
     * moved every slab's bounds, and the simulated sassafras flipped from
     * a kept stem to a rebuilt one (DBH 0.68 -> 0.40 m) over one return
     * 3 cm above the rest. */
    double *zs = malloc(n * sizeof *zs);
    if (!zs) return sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
    for (size_t i = 0; i < n; i++) zs[i] = xyz[3 * i + 2];
    double z0 = s->pos[2], ztop = fmax(z0, sy_select_double(zs, n, n - 1 - n / 2000));
    free(zs);
    double H = ztop - z0;
    if (!(H > 2.0)) return SY_OK;
    /* Slab centroids above the base. */
    double cnt[STEM_SLABS] = {0}, sx[STEM_SLABS] = {0}, sy[STEM_SLABS] = {0}, sz[STEM_SLABS] = {0};
    double hs = H / STEM_SLABS;
    for (size_t i = 0; i < n; i++) {
        const float *p = xyz + 3 * i;
        if (p[2] < z0) continue;
        int b = (int)((p[2] - z0) / hs);
        if (b >= STEM_SLABS) b = STEM_SLABS - 1;
        cnt[b]++;
        sx[b] += p[0];
        sy[b] += p[1];
        sz[b] += p[2];
    }
    /* The axis: a line through the slab centroids weighted by their points,
     * its foot free; and the same through the root. The root is where the
     * stem is seen when it lies on the free line (within twice the
     * centroids' scatter about it), and then the axis goes through it.
     * Otherwise the base slab holds only low crown (a spruce's skirt: the
     * root 2.4 m off a vertical stem, and the axis through it leaning 0.25),
     * and the free line is the stem. */
    double root[2] = {s->pos[0], s->pos[1]}, ax[2];
    double W = 0, Z = 0, ZZ = 0, X[2] = {0, 0}, XZ[2] = {0, 0}, num[2] = {0, 0}, den = 0;
    for (int b = 0; b < STEM_SLABS; b++) {
        if (cnt[b] < 10) continue;
        double dz = sz[b] / cnt[b] - z0;
        W += cnt[b];
        Z += cnt[b] * dz;
        ZZ += cnt[b] * dz * dz;
        for (int k = 0; k < 2; k++) {
            double c = (k ? sy[b] : sx[b]) / cnt[b];
            X[k] += cnt[b] * c;
            XZ[k] += cnt[b] * c * dz;
            num[k] += cnt[b] * dz * (c - root[k]);
        }
        den += cnt[b] * dz * dz;
    }
    double det = W * ZZ - Z * Z;
    if (!(den > 0) || !(det > 0)) return SY_OK;
    double free_foot[2], free_lean[2], scatter = 0;
    for (int k = 0; k < 2; k++) {
        free_lean[k] = (W * XZ[k] - Z * X[k]) / det;
        free_foot[k] = (X[k] - free_lean[k] * Z) / W;
    }
    for (int b = 0; b < STEM_SLABS; b++) {
        if (cnt[b] < 10) continue;
        double dz = sz[b] / cnt[b] - z0;
        scatter += cnt[b] * (pow(sx[b] / cnt[b] - free_foot[0] - free_lean[0] * dz, 2) +
                             pow(sy[b] / cnt[b] - free_foot[1] - free_lean[1] * dz, 2));
    }
    scatter = sqrt(scatter / W);
    if (hypot(free_foot[0] - root[0], free_foot[1] - root[1]) <= STEM_ROOT_ON_AXIS * scatter) {
        ax[0] = num[0] / den;
        ax[1] = num[1] / den;
    } else {
        for (int k = 0; k < 2; k++) {
            root[k] = free_foot[k];
            ax[k] = free_lean[k];
        }
    }
    info->axis[0] = root[0];
    info->axis[1] = root[1];
    info->axis[2] = ax[0];
    info->axis[3] = ax[1];
    /* Crown radius per slab: mean distance of its points from the axis. */
    double R[STEM_SLABS] = {0}, off[STEM_SLABS], tmp[STEM_SLABS];
    for (size_t i = 0; i < n; i++) {
        const float *p = xyz + 3 * i;
        if (p[2] < z0) continue;
        int b = (int)((p[2] - z0) / hs);
        if (b >= STEM_SLABS) b = STEM_SLABS - 1;
        R[b] += hypot(p[0] - root[0] - ax[0] * (p[2] - z0), p[1] - root[1] - ax[1] * (p[2] - z0)) / cnt[b];
    }
    size_t k = 0;
    double ss = 0, lower = 0, upper = 0, nl = 0, nu = 0;
    for (int b = 0; b < STEM_SLABS; b++) {
        if (cnt[b] < 10) continue;
        double dz = sz[b] / cnt[b] - z0;
        off[b] = hypot(sx[b] / cnt[b] - root[0] - ax[0] * dz, sy[b] / cnt[b] - root[1] - ax[1] * dz);
        ss += off[b] * off[b];
        tmp[k++] = R[b];
        if (b < STEM_SLABS / 2) lower += R[b], nl++;
        if (b >= 2 * STEM_SLABS / 3) upper += R[b], nu++;
    }
    if (k < STEM_SLABS / 2 || !nl || !nu) return SY_OK;
    double Rmed = median_of(tmp, k);
    info->crown_radius = Rmed;
    info->axis_rms = sqrt(ss / (double)k);
    info->excurrent = upper / nu < STEM_EXCURRENT_SHARE * (lower / nl);
    /* The foot: the two lowest slabs with points (a slab needs 10 to count). */
    double foot = 0;
    for (int b = 0, got = 0; b < STEM_SLABS && got < 2; b++)
        if (cnt[b] >= 10) foot += 0.5 * R[b], got++;
    info->crown_to_ground = foot >= STEM_FOOT_SHARE * Rmed;
    /* The trunk chain's largest horizontal distance from the axis. */
    for (size_t i = 0; i < m; i++) {
        if (s->branch[i] != 0) continue;
        const float *p = s->pos + 3 * i;
        double d = hypot(p[0] - root[0] - ax[0] * (p[2] - z0), p[1] - root[1] - ax[1] * (p[2] - z0));
        info->excursion = fmax(info->excursion, d);
    }
    if (!(Rmed > 0) || info->axis_rms > STEM_AXIS_RMS_SHARE * Rmed || !info->excurrent || !info->crown_to_ground ||
        info->excursion <= STEM_EXCURSION_SHARE * Rmed || info->excursion <= STEM_EXCURSION_HEIGHT * H ||
        hypot(ax[0], ax[1]) > 0.25)
        return SY_OK;

    /* A cone or a dome. Above its widest slab a cone's radius falls about
     * linearly to the top, a dome's holds near its widest and rounds off:
     * the mean radius over those slabs, as a share of the widest, is 0.60
     * and 0.63 on the simulated balsam fir and Norway spruce, 0.70-0.77 on
     * the black oak, the sassafras and the airborne ahn3_delft (a half
     * ellipse gives pi/4 = 0.79, a cone 0.5). A domed crown is decurrent:
     * its occluded trunk divides inside the crown, so the rebuilt stem stops
     * at the top of the crown's widest part (the highest slab within 0.9 of
     * the widest, kept in 0.25-0.5 of the height) and the colonised limbs
     * spread from there. Run to the top, it was a pole through the dome with
     * a comb of straight limbs: an oak drawn as a spruce. */
    double Rmax = 0, dome = 0, stem_top = H;
    int bmax = -1, nd = 0, bfork = -1;
    for (int b = 0; b < STEM_SLABS; b++)
        if (cnt[b] >= 10 && R[b] > Rmax) Rmax = R[b], bmax = b;
    for (int b = bmax + 1; b < STEM_SLABS; b++)
        if (cnt[b] >= 10) dome += R[b] / Rmax, nd++;
    for (int b = bmax; b < STEM_SLABS && b >= 0; b++)
        if (cnt[b] >= 10 && R[b] >= STEM_FORK_SHARE * Rmax) bfork = b;
    info->dome = nd > 0 ? dome / nd : 0;
    if (fork_domes && info->dome >= STEM_DOME_SHARE) {
        stem_top = fmin(fmax((bfork + 1) * hs, STEM_FORK_MIN * H), STEM_FORK_MAX * H);
        info->fork = stem_top;
    }

    /* Rebuild: stem nodes on the axis from the root to the top, and limbs
     * grown from them into the crown's returns by space colonisation
     * (colonize.c). The geodesic nodes off the stem go: they trace the
     * shell, and hung from the stem at their own heights they were spokes
     * across the crown. Every point joins its nearest new node. */
    double step = fmax(w, H / 48);
    size_t K = (size_t)ceil(stem_top / step) + 1;
    step = stem_top / (double)(K - 1);
    double grow = fmax(2 * w, STEM_LIMB_STEP * Rmed);
    float *tpos = malloc(K * 3 * sizeof *tpos);
    if (!tpos) return sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
    for (size_t t = 0; t < K; t++) {
        double z = z0 + step * (double)t;
        tpos[3 * t] = (float)(root[0] + ax[0] * (z - z0));
        tpos[3 * t + 1] = (float)(root[1] + ax[1] * (z - z0));
        tpos[3 * t + 2] = (float)z;
    }
    sy_code rc = regrow_from_trunk(s, tpos, K, 0, xyz, n, -INFINITY, point_node, wood, grow, err);
    free(tpos);
    if (rc) return rc;
    info->rebuilt = 1;
    measure_stem(xyz, n, z0, H, root, ax, fmax(0.15, 0.2 * Rmed), spacing, info);
    if (!(info->measured_r > 0)) info->fallback_r = 0.5 * H / STEM_SLENDERNESS;
    return SY_OK;
}

void sy_apply_stem_radius(sy_skeleton *s, const sy_stem_info *stem, double gamma, double taper, double spacing,
                          sy_radii_info *ri)
{
    if (!stem->rebuilt || !(gamma > 0)) return;
    size_t m = s->n;
    double *l = malloc((m ? m : 1) * sizeof *l);
    if (!l) return; /* the allometry from the breast-height fit stands */
    sy_skeleton_subtree_lengths(s, l);
    double z0 = s->pos[2], zb = z0 + ri->dbh_z;
    double zm = stem->measured_r > 0 ? stem->measured_z : zb;
    size_t um = 0, ub = 0;
    for (size_t i = 0; i < m; i++) {
        if (s->branch[i] != 0) continue;
        if (fabs(s->pos[3 * i + 2] - zm) < fabs(s->pos[3 * um + 2] - zm)) um = i;
        if (fabs(s->pos[3 * i + 2] - zb) < fabs(s->pos[3 * ub + 2] - zb)) ub = i;
    }
    /* A crown of fronds' stem carries its whole crown at its top: a palm
     * has no secondary growth and its stem barely narrows, by the species'
     * own taper. The pipe model over the stem alone, whose length above a
     * node falls to nothing at its top, thinned the airborne palm's stem
     * from 0.17 m at its foot to 0.07 m at its crown, where its true tree's
     * goes from 0.16 m to 0.12 m. As a length, l[i] / l0 = (1 - taper t)^gamma
     * at the share t of the stem's height gives that linear taper. */
    if (stem->columnar) {
        double top = s->pos[2];
        for (size_t i = 0; i < m; i++)
            if (s->branch[i] == 0) top = fmax(top, s->pos[3 * i + 2]);
        double L = top - s->pos[2] > 0 ? top - s->pos[2] : 1;
        for (size_t i = 0; i < m; i++) {
            double t = fmin(fmax((s->pos[3 * i + 2] - s->pos[2]) / L, 0), 1);
            l[i] = l[0] * pow(1 - taper * t, gamma);
        }
    }
    double inv = 1.0 / gamma, l0 = l[0] > 0 ? l[0] : 1;
    double at_ub = pow(fmax(l[ub] / l0, 1e-9), inv); /* breast height's share of the root's diameter */
    /* A clean circle at breast height on the rebuilt axis, no wider than the
     * stem measured below it, is the trunk itself: it stands (sassafras: a
     * 53-point circle, 4 mm residual, gave the DBH within 1%, and the taper
     * through a run of returns at 1 m put it 28% low). */
    double bh_r = 0.5 * ri->dbh, d_root;
    if (ri->fitted && ri->inliers >= 20 && ri->rms <= 0.05 * bh_r &&
        hypot(ri->centre[0] - s->pos[3 * ub], ri->centre[1] - s->pos[3 * ub + 1]) <= fmax(0.5 * bh_r, 0.15) &&
        (!(stem->measured_r > 0) || bh_r <= 1.1 * stem->measured_r)) {
        d_root = ri->dbh / at_ub;
    } else if (ri->allometric_dbh > 0 && (!(stem->measured_r > 0) || fabs(stem->measured_z - zb) > 1.0)) {
        /* No stem circle near breast height: the pipe model from a circle
         * metres away (balsam fir: a ring of branches at 3 m, DBH 2.1x the
         * truth) is weaker than the species' allometry. */
        ri->fitted = 0;
        ri->rms = 0;
        ri->dbh = ri->allometric_dbh;
        d_root = ri->dbh / at_ub;
    } else {
        double r = stem->measured_r > 0 ? stem->measured_r : stem->fallback_r;
        /* The pipe model from the measured slab to the root, then to breast height. */
        d_root = 2 * r / pow(fmax(l[um] / l0, 1e-9), inv);
        ri->fitted = 0;
        ri->dbh = d_root * at_ub;
        if (stem->measured_r > 0 && stem->upper_r > 0 && stem->upper_z > stem->measured_z) {
            /* Two stem measurements: the taper between them, to breast height. */
            double t = (zb - stem->measured_z) / (stem->upper_z - stem->measured_z);
            ri->dbh = 2 * (stem->measured_r + t * (stem->upper_r - stem->measured_r));
            ri->fitted = zb >= stem->measured_z - 0.3 && zb <= stem->upper_z + 0.3;
            d_root = ri->dbh / at_ub;
        }
        ri->fitted = ri->fitted || (stem->measured_r > 0 && fabs(stem->measured_z - zb) < 0.3);
        ri->rms = stem->measured_r > 0 ? stem->measured_rms : 0;
    }
    ri->d_root = d_root;
    double rmin = fmax(0.25 * spacing, 0.001);
    for (size_t i = 0; i < m; i++) s->radius[i] = (float)fmax(0.5 * d_root * pow(l[i] / l0, inv), rmin);
    for (size_t i = 1; i < m; i++)
        if (s->parent[i] >= 0 && s->radius[i] > s->radius[s->parent[i]]) s->radius[i] = s->radius[s->parent[i]];
    free(l);
}

static double dist3f(const float a[3], const float b[3])
{
    return sqrt(((double)a[0] - b[0]) * ((double)a[0] - b[0]) + ((double)a[1] - b[1]) * ((double)a[1] - b[1]) +
                ((double)a[2] - b[2]) * ((double)a[2] - b[2]));
}

/* Over height slabs of the upper 60 % of the tree (z0 the root, H the
 * height): the median of each slab's (median / 95th percentile) distance of
 * its returns from their centroid (0 when no slab has 50 returns). */
static double crown_fill_ratio(const float *xyz, size_t n, double z0, double H, sy_error *err, sy_code *rc)
{
    enum { SLABS = 10, MIN_PTS = 50 };
    double cx[SLABS] = {0}, cy[SLABS] = {0}, ratio[SLABS];
    size_t cnt[SLABS] = {0}, at[SLABS + 1] = {0};
    double lo = z0 + 0.4 * H, hs = 0.6 * H / SLABS;
    *rc = SY_OK;
    if (!(hs > 0)) return 0;
    for (size_t i = 0; i < n; i++) {
        long b = (long)floor((xyz[3 * i + 2] - lo) / hs);
        if (b < 0 || b >= SLABS) continue;
        cx[b] += xyz[3 * i], cy[b] += xyz[3 * i + 1], cnt[b]++;
    }
    for (int b = 0; b < SLABS; b++) at[b + 1] = at[b] + cnt[b];
    double *r = malloc((at[SLABS] + 1) * sizeof *r);
    if (!r) {
        *rc = sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
        return 0;
    }
    size_t fill[SLABS];
    memcpy(fill, at, sizeof fill);
    for (int b = 0; b < SLABS; b++)
        if (cnt[b]) cx[b] /= (double)cnt[b], cy[b] /= (double)cnt[b];
    for (size_t i = 0; i < n; i++) {
        long b = (long)floor((xyz[3 * i + 2] - lo) / hs);
        if (b < 0 || b >= SLABS) continue;
        r[fill[b]++] = hypot(xyz[3 * i] - cx[b], xyz[3 * i + 1] - cy[b]);
    }
    size_t k = 0;
    for (int b = 0; b < SLABS; b++) {
        if (cnt[b] < MIN_PTS) continue;
        double *v = r + at[b];
        qsort(v, cnt[b], sizeof *v, sy_cmp_double);
        double p95 = v[(size_t)(0.95 * (double)cnt[b])];
        ratio[k++] = p95 > 0 ? v[cnt[b] / 2] / p95 : 0;
    }
    free(r);
    return median_of(ratio, k);
}

sy_code sy_regrow_meandering_crown(sy_skeleton *s, const float *xyz, size_t n, int32_t *point_node,
                                   const uint8_t *wood, double w, double meander, int base_above_root,
                                   sy_stem_info *info, sy_error *err)
{
    if (s->n < 3 || n == 0 || s->parent[0] >= 0) return SY_OK;
    /* The trunk chain: from the root (node 0, breadth-first) through the
     * children of its branch. */
    int32_t *chain = malloc(s->n * sizeof *chain), *child = malloc(s->n * sizeof *child);
    if (!chain || !child) {
        free(chain), free(child);
        return sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
    }
    for (size_t i = 0; i < s->n; i++) child[i] = -1;
    for (size_t i = 1; i < s->n; i++) {
        int32_t p = s->parent[i];
        if (p >= 0 && s->branch[i] == s->branch[p] && child[p] < 0) child[p] = (int32_t)i;
    }
    size_t K = 0;
    for (int32_t v = 0; v >= 0 && K < s->n; v = child[v]) chain[K++] = v;
    free(child);
    float r0[3]; /* the root: s is replaced below */
    memcpy(r0, s->pos, sizeof r0);
    double path = 0, chord = 0, top_z = r0[2], trunk_path = 0;
    size_t base = 0, k0 = base_above_root && K > 1 ? 1 : 0; /* the crown base is measured from chain[k0] */
    const float *t0 = s->pos + 3 * (size_t)chain[k0];
    int past_base = 0;
    for (size_t k = 1; k < K; k++) {
        const float *a = s->pos + 3 * (size_t)chain[k - 1], *b = s->pos + 3 * (size_t)chain[k];
        double step = dist3f(a, b);
        path += step;
        chord = dist3f(r0, b);
        if (k > k0) {
            trunk_path += step;
            if (!past_base && (trunk_path > CROWN_BASE_PATH * dist3f(t0, b) || b[2] - a[2] < 0.5 * step)) past_base = 1;
        }
        if (!past_base) base = k;
    }
    for (size_t i = 0; i < n; i++) top_z = fmax(top_z, xyz[3 * i + 2]);
    info->meander = chord > 0 ? path / chord : 0;
    sy_code rc = SY_OK;
    if (info->meander > meander) info->crown_fill = crown_fill_ratio(xyz, n, r0[2], top_z - r0[2], err, &rc);
    if (rc || !(info->meander > meander) || !(info->crown_fill > CROWN_FOLIAGE_RATIO)) {
        free(chain);
        return rc;
    }
    /* The crown's mean radius about the trunk's top over the returns above
     * it: the limbs grow in steps of a share of it, as the occluded stem's. */
    float top[3];
    memcpy(top, s->pos + 3 * (size_t)chain[base], sizeof top);
    double sum = 0;
    size_t cnt = 0;
    for (size_t i = 0; i < n; i++)
        if (xyz[3 * i + 2] > top[2]) sum += hypot(xyz[3 * i] - top[0], xyz[3 * i + 1] - top[1]), cnt++;
    float *trunk = malloc((base + 1) * 3 * sizeof *trunk);
    if (!trunk) {
        free(chain);
        return sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
    }
    for (size_t k = 0; k <= base; k++) memcpy(trunk + 3 * k, s->pos + 3 * (size_t)chain[k], 3 * sizeof *trunk);
    free(chain);
    double crown_r = cnt ? sum / (double)cnt : 0;
    rc = regrow_from_trunk(s, trunk, base + 1, 0, xyz, n, top[2], point_node, wood,
                           fmax(2 * w, STEM_LIMB_STEP * crown_r), err);
    free(trunk);
    if (!rc) info->crown_regrown = 1, info->crown_base = top[2] - r0[2];
    return rc;
}

sy_code sy_rebuild_unseen_stem(sy_skeleton *s, const float *xyz, size_t n, int32_t *point_node, const uint8_t *wood,
                               double w, double spacing, double ground, int limbs, sy_stem_info *info, sy_error *err)
{
    if (n < 16) return SY_OK;
    double zlo = INFINITY, ztop = -INFINITY;
    for (size_t i = 0; i < n; i++) zlo = fmin(zlo, xyz[3 * i + 2]), ztop = fmax(ztop, xyz[3 * i + 2]);
    if (!isfinite(ground)) ground = zlo;
    double H = ztop - ground, D = ztop - zlo;
    info->crown_gap = zlo - ground;
    if (!(H > 2.0) || !(D > 0) || !(spacing >= UNSEEN_SKIRT_SPACING ||
                                     info->crown_gap >= fmax(1.0, UNSEEN_STEM_GAP * H)))
        return SY_OK;
    /* The stem stands under the middle of the crown: the median x and y of
     * its returns (a crown seen from above has no lean to measure). */
    double *v = malloc(n * sizeof *v), axis[2];
    if (!v) return sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
    for (int k = 0; k < 2; k++) {
        for (size_t i = 0; i < n; i++) v[i] = xyz[3 * i + k];
        axis[k] = median_of(v, n);
    }
    if (info->crown_gap < fmax(1.0, UNSEEN_STEM_GAP * H) && !(spacing >= UNSEEN_SPACING)) {
        /* A crown low over the ground in a coarse scan: unseen unless its
         * lowest returns show a bole near the axis. */
        for (size_t i = 0; i < n; i++) v[i] = hypot(xyz[3 * i] - axis[0], xyz[3 * i + 1] - axis[1]);
        double near_r = fmax(UNSEEN_BOLE_NEAR_MIN, UNSEEN_BOLE_NEAR * median_of(v, n));
        size_t low = 0, bole = 0;
        for (size_t i = 0; i < n; i++)
            if (xyz[3 * i + 2] < ground + UNSEEN_LOW_BAND * H)
                low++, bole += hypot(xyz[3 * i] - axis[0], xyz[3 * i + 1] - axis[1]) < near_r;
        if (bole >= UNSEEN_BOLE_MIN && (double)bole > UNSEEN_BOLE_SHARE * (double)low) {
            free(v);
            return SY_OK;
        }
    }
    free(v);
    /* The crown's shape, as the occluded stem's (sy_rebuild_occluded_stem):
     * per slab the mean distance of the returns from the axis; a dome's
     * stem divides where its widest part ends, a cone's runs to the top. */
    double R[UNSEEN_SLABS] = {0}, hs = D / UNSEEN_SLABS, Rmax = 0, dome = 0, med[UNSEEN_SLABS];
    size_t cnt[UNSEEN_SLABS] = {0};
    for (size_t i = 0; i < n; i++) {
        int b = (int)((xyz[3 * i + 2] - zlo) / hs);
        b = b < 0 ? 0 : b >= UNSEEN_SLABS ? UNSEEN_SLABS - 1 : b;
        R[b] += hypot(xyz[3 * i] - axis[0], xyz[3 * i + 1] - axis[1]), cnt[b]++;
    }
    int bmax = -1, bfork = -1, nd = 0, k = 0;
    for (int b = 0; b < UNSEEN_SLABS; b++) {
        if (cnt[b] < UNSEEN_SLAB_MIN) continue;
        R[b] /= (double)cnt[b];
        med[k++] = R[b];
        if (R[b] > Rmax) Rmax = R[b], bmax = b;
    }
    if (bmax < 0) return SY_OK;
    for (int b = bmax + 1; b < UNSEEN_SLABS; b++)
        if (cnt[b] >= UNSEEN_SLAB_MIN) dome += R[b] / Rmax, nd++;
    for (int b = bmax; b < UNSEEN_SLABS; b++)
        if (cnt[b] >= UNSEEN_SLAB_MIN && R[b] >= STEM_FORK_SHARE * Rmax) bfork = b;
    info->dome = nd > 0 ? dome / nd : 1;
    info->crown_radius = median_of(med, (size_t)k);
    info->axis[0] = axis[0], info->axis[1] = axis[1], info->axis[2] = info->axis[3] = 0;
    double stem_top = H;
    if (info->dome >= STEM_DOME_SHARE) {
        stem_top = info->crown_gap + fmin(fmax((bfork + 1) * hs, STEM_FORK_MIN * D), STEM_FORK_MAX * D);
        info->fork = stem_top;
    }
    double step = fmin(w, H / 48); /* a node every level set or finer: the sanity checks count them */
    size_t K = (size_t)ceil(stem_top / step) + 1;
    step = stem_top / (double)(K - 1);
    float *tpos = malloc(K * 3 * sizeof *tpos);
    if (!tpos) return sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
    for (size_t t = 0; t < K; t++) {
        tpos[3 * t] = (float)axis[0];
        tpos[3 * t + 1] = (float)axis[1];
        tpos[3 * t + 2] = (float)(ground + step * (double)t);
    }
    /* A domed crown's trunk divides where it stops: limbs grow from it into
     * the returns by space colonisation, as the occluded stem's. A trunk
     * that runs to the top carries its lobes itself (every return joins its
     * nearest trunk node) and synthesis grows the limbs inside its lobes
     * (docs/synthesize.md, the scaffold): limbs colonised there, in steps of
     * 2 level sets (1.7-2.7 m), stood off the trunk like crossarms (the
     * beech's IoU against its true tree 0.541 with them, 0.601 without);
     * under a dome the crown above the fork lost its support without them
     * (the black oak 0.588 -> 0.461, height -37 %).
     * Limbs only from the fork, where the trunk divides: sprouting from
     * every trunk node in a crown that reaches down to the bole (the
     * airborne black oak's, 0.5 m over the ground), they stood off it as a
     * comb of level rods (IoU 0.650 with the comb, 0.632 without).
     * A crown of fronds grows none: a palm's stem carries no limbs, and
     * colonised ones stood as 7-10 cm stumps round the airborne palm's
     * crown, under the fronds that synthesis lays from the stem's top. */
    size_t sprout = info->fork > 0 && limbs ? K - 1 : K;
    info->columnar = !limbs;
    sy_code rc = regrow_from_trunk(s, tpos, K, sprout, xyz, n, -INFINITY, point_node, wood,
                                   UNSEEN_LIMB_STEP * info->crown_radius, err);
    free(tpos);
    if (rc) return rc;
    info->rebuilt = info->stem_unseen = 1;
    info->fallback_r = 0.5 * H / STEM_SLENDERNESS;
    return SY_OK;
}
