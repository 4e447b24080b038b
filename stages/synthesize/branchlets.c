/* Species branchlets from a bracketed stochastic L-system (Prusinkiewicz &
 * Lindenmayer 1990) partitioned into patches with docking points (Pirk 2013
 * §3.4). See branchlets.h and docs/synthesize.md. */
#include "stages/synthesize/branchlets.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "stages/core/fileio.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif
#define MAX_WORD 200000 /* symbols after rewriting; a longer word is a grammar error */

uint64_t sy_synth_rand(uint64_t *state)
{
    uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

double sy_synth_uniform(uint64_t *state) { return (double)(sy_synth_rand(state) >> 11) * (1.0 / 9007199254740992.0); }

sy_lsystem sy_lsystem_default(void)
{
    sy_lsystem value_, *ls = &value_;
    memset(ls, 0, sizeof *ls);
    snprintf(ls->axiom, sizeof ls->axiom, "A");
    ls->rules[0] = (sy_lsys_rule){'A', "F[+LA]/F[-LA]/FA", 0.6f};
    ls->rules[1] = (sy_lsys_rule){'A', "F[&LA]/FL", 0.4f};
    ls->n_rules = 2;
    ls->iterations = 5;
    ls->count = 24;
    ls->angle = 40, ls->angle_v = 12;
    ls->roll = 137.5f;
    ls->step = 0.16f, ls->step_decay = 0.8f, ls->step_v = 0.3f;
    ls->tropism = 0.3f;
    ls->elevation = 30, ls->elevation_v = 35;
    ls->tip_radius = 0.002f;
    ls->pipe_exponent = 2.2f;
    ls->leaves_per_l = 3;
    ls->leaf_angle = 50;
    ls->leaf_size = 0.25f;
    ls->patch_depth = 2;
    ls->leaf_density = 1.5f;
    ls->max_depth = 7;
    return value_;
}

sy_code sy_lsystem_check(const sy_lsystem *ls, sy_error *err)
{
#define RANGE(f, lo, hi)                                                                                       \
    if (!((double)ls->f >= (lo) && (double)ls->f <= (hi)))                                                     \
        return sy_fail(err, SY_EUSAGE, "branchlets: " #f " = %g is outside [%g, %g]", (double)ls->f, (double)(lo), \
                       (double)(hi));
    RANGE(iterations, 1, 8) RANGE(count, 20, 30) RANGE(angle, 0, 180) RANGE(angle_v, 0, 90) RANGE(roll, -360, 360)
    RANGE(step, 1e-3, 5) RANGE(step_decay, 0.1, 1.5) RANGE(step_v, 0, 1) RANGE(tropism, -10, 10)
    RANGE(elevation, -90, 90) RANGE(elevation_v, 0, 90) RANGE(tip_radius, 1e-4, 0.1) RANGE(pipe_exponent, 1, 4)
    RANGE(leaves_per_l, 0, 64) RANGE(leaf_angle, 0, 90) RANGE(leaf_size, 1e-3, 3) RANGE(patch_depth, 1, 8)
    RANGE(leaf_density, 0, 1000) RANGE(max_depth, 1, 32)
#undef RANGE
    if (!ls->axiom[0]) return sy_fail(err, SY_EUSAGE, "branchlets: the axiom is empty");
    for (int i = 0; i < ls->n_rules; i++)
        if (!(ls->rules[i].weight > 0)) return sy_fail(err, SY_EUSAGE, "branchlets: rule %d has weight <= 0", i + 1);
    return SY_OK;
}

typedef struct {
    const char *name;
    size_t offset;
    int is_int;
} lsys_key;

#define K(f, i) {#f, offsetof(sy_lsystem, f), i}
static const lsys_key keys[] = {
    K(iterations, 1), K(count, 1), K(angle, 0), K(angle_v, 0), K(roll, 0), K(step, 0), K(step_decay, 0),
    K(step_v, 0), K(tropism, 0), K(elevation, 0), K(elevation_v, 0), K(tip_radius, 0), K(pipe_exponent, 0),
    K(leaves_per_l, 1), K(leaf_angle, 0), K(leaf_size, 0), K(patch_depth, 1), K(leaf_density, 0),
    K(max_depth, 1),
};
#undef K

static char *trim(char *s)
{
    while (isspace((unsigned char)*s)) s++;
    char *e = s + strlen(s);
    while (e > s && isspace((unsigned char)e[-1])) *--e = 0;
    return s;
}

/* A word: the turtle symbols and variables, nothing else (spaces dropped). */
static int copy_word(const char *in, char *out, size_t cap)
{
    size_t n = 0;
    int depth = 0;
    for (; *in; in++) {
        unsigned char c = (unsigned char)*in;
        if (isspace(c)) continue;
        if (!(isupper(c) || strchr("+-&^/\\[]", c))) return 0;
        depth += c == '[' ? 1 : c == ']' ? -1 : 0;
        if (depth < 0 || n + 1 >= cap) return 0;
        out[n++] = (char)c;
    }
    out[n] = 0;
    return depth == 0 && n > 0;
}

sy_code sy_lsystem_parse(const char *text, size_t size, const char *path, sy_lsystem *ls, sy_error *err)
{
    *ls = sy_lsystem_default();
    ls->n_rules = 0;
    int in_section = 0, axiom_seen = 0, line_no = 0;
    size_t pos = 0;
    while (pos < size) {
        char line[512];
        size_t e = pos;
        while (e < size && text[e] != '\n') e++;
        line_no++;
        if (e - pos >= sizeof line) return sy_fail(err, SY_EINPUT, "%s:%d: line too long", path, line_no);
        memcpy(line, text + pos, e - pos);
        line[e - pos] = 0;
        pos = e + 1;
        for (char *c = line; *c; c++)
            if (*c == ';' || *c == '#') *c = 0;
        char *s = trim(line);
        if (!*s) continue;
        if (*s == '[') {
            if (strcasecmp(s, "[Branchlets]") != 0)
                return sy_fail(err, SY_EINPUT, "%s:%d: unknown section %s (expected [Branchlets])", path, line_no, s);
            in_section = 1;
            continue;
        }
        if (!in_section) return sy_fail(err, SY_EINPUT, "%s:%d: key outside [Branchlets]", path, line_no);
        char *eq = strchr(s, '=');
        if (!eq) return sy_fail(err, SY_EINPUT, "%s:%d: expected key = value", path, line_no);
        *eq = 0;
        char *key = trim(s), *val = trim(eq + 1);
        if (strcasecmp(key, "axiom") == 0) {
            if (!copy_word(val, ls->axiom, sizeof ls->axiom))
                return sy_fail(err, SY_EINPUT, "%s:%d: the axiom is not a balanced word of A-Z + - & ^ / \\ [ ]", path,
                               line_no);
            axiom_seen = 1;
            continue;
        }
        if (strcasecmp(key, "rule") == 0) {
            if (ls->n_rules >= SY_LSYS_MAX_RULES)
                return sy_fail(err, SY_EINPUT, "%s:%d: more than %d rules", path, line_no, SY_LSYS_MAX_RULES);
            sy_lsys_rule *r = &ls->rules[ls->n_rules];
            char *arrow = strstr(val, "->");
            if (!arrow) return sy_fail(err, SY_EINPUT, "%s:%d: a rule reads A -> WORD [: weight]", path, line_no);
            *arrow = 0;
            char *pred = trim(val), *succ = arrow + 2, *colon = strchr(succ, ':');
            r->weight = 1;
            if (colon) {
                *colon = 0;
                char *end;
                double w = strtod(trim(colon + 1), &end);
                if (*trim(end) || !(w > 0) || !isfinite(w))
                    return sy_fail(err, SY_EINPUT, "%s:%d: a rule's weight must be a number > 0", path, line_no);
                r->weight = (float)w;
            }
            if (strlen(pred) != 1 || !isupper((unsigned char)pred[0]) || pred[0] == 'F' || pred[0] == 'L')
                return sy_fail(err, SY_EINPUT, "%s:%d: a rule rewrites one variable A-Z other than F and L", path,
                               line_no);
            r->pred = pred[0];
            if (!copy_word(succ, r->succ, sizeof r->succ))
                return sy_fail(err, SY_EINPUT, "%s:%d: the successor is not a balanced word of A-Z + - & ^ / \\ [ ]",
                               path, line_no);
            ls->n_rules++;
            continue;
        }
        const lsys_key *k = NULL;
        for (size_t i = 0; i < sizeof keys / sizeof keys[0]; i++)
            if (strcasecmp(key, keys[i].name) == 0) k = &keys[i];
        if (!k) return sy_fail(err, SY_EINPUT, "%s:%d: unknown key %s", path, line_no, key);
        char *end;
        double d = strtod(val, &end);
        if (end == val || *trim(end) || !isfinite(d))
            return sy_fail(err, SY_EINPUT, "%s:%d: %s: not a number: %s", path, line_no, key, val);
        if (k->is_int) {
            if (d != floor(d) || fabs(d) > 1e6)
                return sy_fail(err, SY_EINPUT, "%s:%d: %s must be an integer", path, line_no, key);
            *(int *)((char *)ls + k->offset) = (int)d;
        } else {
            *(float *)((char *)ls + k->offset) = (float)d;
        }
    }
    if (!axiom_seen || ls->n_rules == 0)
        return sy_fail(err, SY_EINPUT, "%s: a [Branchlets] section needs an axiom and at least one rule", path);
    sy_error e2;
    if (sy_lsystem_check(ls, &e2)) return sy_fail(err, SY_EINPUT, "%s: %s", path, e2.msg);
    return SY_OK;
}

sy_code sy_lsystem_load(const char *path, sy_lsystem *ls, sy_error *err)
{
    sy_buffer buf;
    sy_code rc = sy_read_file(path, &buf, err);
    if (rc) return rc;
    rc = sy_lsystem_parse((const char *)buf.data, buf.size, path, ls, err);
    sy_buffer_free(&buf);
    return rc;
}

/* ---- Rewriting ---- */

static sy_code rewrite(const sy_lsystem *ls, uint64_t *rng, char **out, sy_error *err)
{
    size_t cap = MAX_WORD + 1;
    char *a = malloc(cap), *b = malloc(cap);
    if (!a || !b) {
        free(a), free(b);
        return sy_fail(err, SY_EINTERNAL, "branchlets: out of memory");
    }
    snprintf(a, cap, "%s", ls->axiom);
    for (int it = 0; it < ls->iterations; it++) {
        size_t n = 0;
        for (const char *c = a; *c; c++) {
            double total = 0;
            for (int r = 0; r < ls->n_rules; r++)
                if (ls->rules[r].pred == *c) total += ls->rules[r].weight;
            const char *succ = NULL;
            if (total > 0) {
                double u = sy_synth_uniform(rng) * total;
                for (int r = 0; r < ls->n_rules && !succ; r++)
                    if (ls->rules[r].pred == *c && (u -= ls->rules[r].weight) < 0) succ = ls->rules[r].succ;
                if (!succ) /* rounding: the last matching rule */
                    for (int r = ls->n_rules - 1; r >= 0 && !succ; r--)
                        if (ls->rules[r].pred == *c) succ = ls->rules[r].succ;
            }
            size_t len = succ ? strlen(succ) : 1;
            if (n + len > MAX_WORD) {
                free(a), free(b);
                return sy_fail(err, SY_EINPUT, "branchlets: the word grows beyond %d symbols after %d iterations",
                               MAX_WORD, it + 1);
            }
            if (succ) memcpy(b + n, succ, len);
            else b[n] = *c;
            n += len;
        }
        b[n] = 0;
        char *t = a;
        a = b, b = t;
    }
    free(b);
    *out = a;
    return SY_OK;
}

/* ---- Turtle ---- */

static void v_rot(float v[3], const float axis[3], double ang)
{
    double c = cos(ang), s = sin(ang), d = axis[0] * v[0] + axis[1] * v[1] + axis[2] * v[2];
    float cr[3] = {axis[1] * v[2] - axis[2] * v[1], axis[2] * v[0] - axis[0] * v[2], axis[0] * v[1] - axis[1] * v[0]};
    for (int k = 0; k < 3; k++) v[k] = (float)(v[k] * c + cr[k] * s + axis[k] * d * (1 - c));
}

static void v_norm(float v[3])
{
    double l = sqrt((double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2]);
    if (l > 1e-12)
        for (int k = 0; k < 3; k++) v[k] = (float)(v[k] / l);
}

static void v_cross(const float a[3], const float b[3], float o[3])
{
    o[0] = a[1] * b[2] - a[2] * b[1], o[1] = a[2] * b[0] - a[0] * b[2], o[2] = a[0] * b[1] - a[1] * b[0];
}

typedef struct {
    float pos[3], h[3], l[3], u[3];
    int32_t node;
    int depth, pending;
} turtle;

typedef struct { /* one complete branchlet, before partitioning */
    size_t n, nl;
    float *pos, *radius;
    int32_t *parent;
    uint8_t *starts, *depth;
    float *lpos, *ldir, *lnorm;
    int32_t *lnode;
} raw_branchlet;

static void raw_free(raw_branchlet *b)
{
    free(b->pos), free(b->radius), free(b->parent), free(b->starts), free(b->depth);
    free(b->lpos), free(b->ldir), free(b->lnorm), free(b->lnode);
    memset(b, 0, sizeof *b);
}

/* Random in [-1, 1). */
static double sym(uint64_t *rng) { return 2 * sy_synth_uniform(rng) - 1; }

/* Interprets the word: F draws a node (one per F, so the word sizes the
 * arrays exactly), L leaves at the turtle, + - yaw, & ^ pitch, / \ roll,
 * [ ] push and pop. The first heading rises elev above the +X axis. */
static sy_code interpret(const sy_lsystem *ls, const char *word, double elev, double tip_scale, uint64_t *rng,
                         raw_branchlet *b, sy_error *err)
{
    size_t nf = 0, nlv = 0, maxd = 1;
    int d = 0;
    for (const char *c = word; *c; c++) {
        nf += *c == 'F';
        nlv += *c == 'L';
        d += *c == '[' ? 1 : *c == ']' ? -1 : 0;
        if ((size_t)d + 1 > maxd) maxd = (size_t)d + 1;
    }
    nlv *= (size_t)ls->leaves_per_l;
    memset(b, 0, sizeof *b);
    b->pos = malloc((3 * nf + 3) * sizeof(float));
    b->radius = malloc((nf + 1) * sizeof(float));
    b->parent = malloc((nf + 1) * sizeof(int32_t));
    b->starts = malloc(nf + 1);
    b->depth = malloc(nf + 1);
    b->lpos = malloc((3 * nlv + 3) * sizeof(float));
    b->ldir = malloc((3 * nlv + 3) * sizeof(float));
    b->lnorm = malloc((3 * nlv + 3) * sizeof(float));
    b->lnode = malloc((nlv + 1) * sizeof(int32_t));
    turtle *stack = malloc(maxd * sizeof *stack);
    if (!b->pos || !b->radius || !b->parent || !b->starts || !b->depth || !b->lpos || !b->ldir || !b->lnorm ||
        !b->lnode || !stack) {
        free(stack);
        raw_free(b);
        return sy_fail(err, SY_EINTERNAL, "branchlets: out of memory");
    }
    const double deg = M_PI / 180;
    turtle t = {{0, 0, 0}, {(float)cos(elev), 0, (float)sin(elev)}, {0, 1, 0}, {0}, -1, 0, 1};
    v_cross(t.h, t.l, t.u);
    size_t sp = 0;
    for (const char *c = word; *c; c++) {
        switch (*c) {
        case 'F': {
            double len = ls->step * pow(ls->step_decay, t.depth) * (1 + ls->step_v * sym(rng));
            /* Tropism (ABOP eq. 2.4 in small steps): bend H toward -Z. */
            float g[3] = {0, 0, -1};
            float tor[3];
            v_cross(t.h, g, tor);
            double m = sqrt((double)tor[0] * tor[0] + (double)tor[1] * tor[1] + (double)tor[2] * tor[2]);
            if (m > 1e-6) {
                for (int k = 0; k < 3; k++) tor[k] = (float)(tor[k] / m);
                double a = ls->tropism * len * m;
                v_rot(t.h, tor, a), v_rot(t.l, tor, a), v_rot(t.u, tor, a);
            }
            for (int k = 0; k < 3; k++) t.pos[k] += (float)(t.h[k] * len);
            size_t i = b->n++;
            memcpy(b->pos + 3 * i, t.pos, sizeof t.pos);
            b->parent[i] = t.node;
            b->starts[i] = (uint8_t)(t.pending || t.node < 0);
            b->depth[i] = (uint8_t)(t.depth > 255 ? 255 : t.depth);
            b->radius[i] = 0;
            t.node = (int32_t)i;
            t.pending = 0;
            break;
        }
        case 'L':
            if (t.node < 0) break;
            for (int k = 0; k < ls->leaves_per_l; k++) {
                size_t i = b->nl++;
                double az = 2 * M_PI * sy_synth_uniform(rng), a = ls->leaf_angle * deg * (0.7 + 0.6 * sy_synth_uniform(rng));
                float dir[3], nrm[3];
                for (int q = 0; q < 3; q++)
                    dir[q] = (float)(cos(a) * t.h[q] + sin(a) * (cos(az) * t.l[q] + sin(az) * t.u[q]));
                v_norm(dir);
                /* Blades face up, as leaves turn to the light. */
                float z[3] = {0, 0, 1};
                double dz = dir[2];
                for (int q = 0; q < 3; q++) nrm[q] = (float)(z[q] - dz * dir[q]);
                if (fabs(dz) > 0.999) memcpy(nrm, t.u, sizeof nrm);
                v_norm(nrm);
                /* Along the last internode, not all at its end. */
                double back = 0.6 * sy_synth_uniform(rng) * ls->step * pow(ls->step_decay, t.depth);
                for (int q = 0; q < 3; q++) b->lpos[3 * i + q] = (float)(t.pos[q] - t.h[q] * back);
                memcpy(b->ldir + 3 * i, dir, sizeof dir);
                memcpy(b->lnorm + 3 * i, nrm, sizeof nrm);
                b->lnode[i] = t.node;
            }
            break;
        case '+': case '-': {
            double a = (ls->angle + ls->angle_v * sym(rng)) * deg * (*c == '+' ? 1 : -1);
            v_rot(t.h, t.u, a), v_rot(t.l, t.u, a);
            break;
        }
        case '&': case '^': {
            double a = (ls->angle + ls->angle_v * sym(rng)) * deg * (*c == '&' ? 1 : -1);
            v_rot(t.h, t.l, a), v_rot(t.u, t.l, a);
            break;
        }
        case '/': case '\\': {
            double a = ls->roll * deg * (*c == '/' ? 1 : -1);
            v_rot(t.l, t.h, a), v_rot(t.u, t.h, a);
            break;
        }
        case '[':
            stack[sp++] = t;
            t.depth++;
            t.pending = 1;
            break;
        case ']':
            t = stack[--sp];
            break;
        default:
            break;
        }
    }
    free(stack);
    /* Pipe model: r^e of a node is the sum over its children's, tips carry tip_radius. */
    double e = ls->pipe_exponent, rt = pow(ls->tip_radius * tip_scale, e);
    double *acc = calloc(b->n + 1, sizeof *acc);
    if (!acc) {
        raw_free(b);
        return sy_fail(err, SY_EINTERNAL, "branchlets: out of memory");
    }
    for (size_t i = b->n; i-- > 0;) {
        if (acc[i] == 0) acc[i] = rt;
        if (b->parent[i] >= 0) acc[b->parent[i]] += acc[i];
    }
    for (size_t i = 0; i < b->n; i++) b->radius[i] = (float)pow(acc[i], 1 / e);
    free(acc);
    return SY_OK;
}

/* Partitions raw into patches: a side stem opening at a bracket depth that is a
 * multiple of patch_depth starts a new patch whose attachment node becomes a
 * docking point of the patch holding it. */
static sy_code partition(const sy_lsystem *ls, const raw_branchlet *b, uint64_t *rng, sy_branchlets *out,
                         sy_error *err)
{
    if (b->n == 0) return SY_OK;
    int32_t *patch_of = malloc(b->n * sizeof *patch_of), *local = malloc(b->n * sizeof *local);
    int32_t *first = malloc(b->n * sizeof *first);
    if (!patch_of || !local || !first) {
        free(patch_of), free(local), free(first);
        return sy_fail(err, SY_EINTERNAL, "branchlets: out of memory");
    }
    size_t np = 0;
    for (size_t i = 0; i < b->n; i++) {
        int32_t p = b->parent[i];
        int new_patch = p < 0 || (b->starts[i] && b->depth[i] % ls->patch_depth == 0);
        if (new_patch) {
            first[np] = (int32_t)i;
            patch_of[i] = (int32_t)np++;
        } else {
            patch_of[i] = patch_of[p];
        }
    }
    size_t base = out->n_patches;
    sy_patch *grown = realloc(out->patches, (base + np) * sizeof *grown);
    if (!grown) {
        free(patch_of), free(local), free(first);
        return sy_fail(err, SY_EINTERNAL, "branchlets: out of memory");
    }
    out->patches = grown;
    memset(out->patches + base, 0, np * sizeof *grown);
    out->n_patches += np;
    sy_code rc = SY_OK;
    for (size_t q = 0; q < np && !rc; q++) {
        sy_patch *P = &out->patches[base + q];
        size_t nn = 0, nd = 0, nl = 0;
        for (size_t i = 0; i < b->n; i++) {
            if (patch_of[i] == (int32_t)q) local[i] = (int32_t)nn++;
            else if ((size_t)patch_of[i] > q && b->parent[i] >= 0 && patch_of[b->parent[i]] == (int32_t)q &&
                     first[patch_of[i]] == (int32_t)i)
                nd++;
        }
        for (size_t k = 0; k < b->nl; k++) nl += patch_of[b->lnode[k]] == (int32_t)q;
        P->pos = malloc((3 * nn + 3) * sizeof(float));
        P->radius = malloc((nn + 1) * sizeof(float));
        P->parent = malloc((nn + 1) * sizeof(int32_t));
        P->starts_branch = malloc(nn + 1);
        P->docks = malloc((nd + 1) * sizeof *P->docks);
        P->leaf_pos = malloc((3 * nl + 3) * sizeof(float));
        P->leaf_dir = malloc((3 * nl + 3) * sizeof(float));
        P->leaf_normal = malloc((3 * nl + 3) * sizeof(float));
        P->leaf_node = malloc((nl + 1) * sizeof(int32_t));
        if (!P->pos || !P->radius || !P->parent || !P->starts_branch || !P->docks || !P->leaf_pos || !P->leaf_dir ||
            !P->leaf_normal || !P->leaf_node) {
            rc = sy_fail(err, SY_EINTERNAL, "branchlets: out of memory");
            break;
        }
        int32_t f = first[q];
        const float *root = b->parent[f] >= 0 ? b->pos + 3 * b->parent[f] : (const float[3]){0, 0, 0};
        float dir[3] = {b->pos[3 * f] - root[0], b->pos[3 * f + 1] - root[1], b->pos[3 * f + 2] - root[2]};
        v_norm(dir);
        /* Rotate about Z so the root direction has azimuth 0. */
        double az = atan2(dir[1], dir[0]), c = cos(-az), s = sin(-az);
#define XF(dst, src)                                                                                            \
    do {                                                                                                        \
        float x_ = (src)[0] - root[0], y_ = (src)[1] - root[1];                                                  \
        (dst)[0] = (float)(c * x_ - s * y_), (dst)[1] = (float)(s * x_ + c * y_), (dst)[2] = (src)[2] - root[2]; \
    } while (0)
#define RF(dst, src)                                                                                            \
    do {                                                                                                        \
        (dst)[0] = (float)(c * (src)[0] - s * (src)[1]), (dst)[1] = (float)(s * (src)[0] + c * (src)[1]);         \
        (dst)[2] = (src)[2];                                                                                    \
    } while (0)
        RF(P->dir, dir);
        v_norm(P->dir);
        P->elevation = (float)asin(P->dir[2] > 1 ? 1 : P->dir[2] < -1 ? -1 : P->dir[2]);
        P->elevation_cos = cos(P->elevation), P->elevation_sin = sin(P->elevation);
        P->thickness = b->radius[f];
        double ext = 0;
        for (size_t i = 0; i < b->n; i++) {
            if (patch_of[i] != (int32_t)q) continue;
            size_t j = (size_t)local[i];
            XF(P->pos + 3 * j, b->pos + 3 * i);
            P->radius[j] = b->radius[i] < P->thickness ? b->radius[i] : P->thickness;
            P->parent[j] = (int32_t)i == f ? -1 : local[b->parent[i]];
            P->starts_branch[j] = (uint8_t)((int32_t)i == f || b->starts[i]);
            double d = sqrt((double)P->pos[3 * j] * P->pos[3 * j] + (double)P->pos[3 * j + 1] * P->pos[3 * j + 1] +
                            (double)P->pos[3 * j + 2] * P->pos[3 * j + 2]);
            if (d > ext) ext = d;
        }
        P->n_nodes = nn;
        for (size_t i = 0; i < b->n; i++) {
            if (!((size_t)patch_of[i] > q && b->parent[i] >= 0 && patch_of[b->parent[i]] == (int32_t)q &&
                  first[patch_of[i]] == (int32_t)i))
                continue;
            sy_dock *D = &P->docks[P->n_docks++];
            const float *a = b->pos + 3 * b->parent[i];
            XF(D->pos, a);
            float dd[3] = {b->pos[3 * i] - a[0], b->pos[3 * i + 1] - a[1], b->pos[3 * i + 2] - a[2]};
            v_norm(dd);
            RF(D->dir, dd);
            D->node = local[b->parent[i]];
            /* Strictly thinner than where it docks (a lone side stem carries
             * its parent's whole pipe otherwise). */
            D->thickness = b->radius[i] < 0.95f * P->radius[D->node] ? b->radius[i] : 0.95f * P->radius[D->node];
        }
        /* Leaves in a stored random order (Fisher-Yates). */
        size_t *ord = malloc((nl + 1) * sizeof *ord), m = 0;
        if (!ord) {
            rc = sy_fail(err, SY_EINTERNAL, "branchlets: out of memory");
            break;
        }
        for (size_t k = 0; k < b->nl; k++)
            if (patch_of[b->lnode[k]] == (int32_t)q) ord[m++] = k;
        for (size_t k = m; k > 1; k--) {
            size_t r = (size_t)(sy_synth_rand(rng) % k), t = ord[k - 1];
            ord[k - 1] = ord[r], ord[r] = t;
        }
        for (size_t k = 0; k < m; k++) {
            size_t src = ord[k];
            XF(P->leaf_pos + 3 * k, b->lpos + 3 * src);
            RF(P->leaf_dir + 3 * k, b->ldir + 3 * src);
            RF(P->leaf_normal + 3 * k, b->lnorm + 3 * src);
            P->leaf_node[k] = local[b->lnode[src]];
            const float *lp = P->leaf_pos + 3 * k;
            double d = sqrt((double)lp[0] * lp[0] + (double)lp[1] * lp[1] + (double)lp[2] * lp[2]);
            if (d > ext) ext = d;
        }
#undef XF
#undef RF
        P->n_leaves = m;
        P->extent = (float)ext;
        out->n_docks += P->n_docks;
        out->n_leaves += m;
        free(ord);
    }
    free(patch_of), free(local), free(first);
    return rc;
}

sy_code sy_branchlets_generate(const sy_lsystem *ls, uint64_t seed, sy_branchlets *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    sy_code rc = sy_lsystem_check(ls, err);
    if (rc) return rc;
    uint64_t rng = seed ^ 0x5EEDB4A9C4E7ull;
    for (int i = 0; i < ls->count && !rc; i++) {
        char *word = NULL;
        if ((rc = rewrite(ls, &rng, &word, err))) break;
        double elev = (ls->elevation + ls->elevation_v * sym(&rng)) * M_PI / 180;
        double tip = 0.8 + 0.4 * sy_synth_uniform(&rng); /* thickness varies among branchlets */
        raw_branchlet b;
        rc = interpret(ls, word, elev, tip, &rng, &b, err);
        free(word);
        if (rc) break;
        rc = partition(ls, &b, &rng, out, err);
        raw_free(&b);
        out->n_branchlets++;
    }
    if (!rc && out->n_patches == 0) rc = sy_fail(err, SY_EINPUT, "branchlets: the grammar draws no F segment");
    if (rc) sy_branchlets_free(out);
    return rc;
}

void sy_branchlets_free(sy_branchlets *b)
{
    for (size_t i = 0; i < b->n_patches; i++) {
        sy_patch *p = &b->patches[i];
        free(p->pos), free(p->radius), free(p->parent), free(p->starts_branch), free(p->docks);
        free(p->leaf_pos), free(p->leaf_dir), free(p->leaf_normal), free(p->leaf_node);
    }
    free(b->patches);
    memset(b, 0, sizeof *b);
}
