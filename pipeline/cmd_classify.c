/* sylva classify [--model M] SCANS...: the species of each scanned tree with
 * its probability vector and confidence; unconfident trees with positions
 * take the vote of their confident neighbours (classify/vote.c). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "classify/classify.h"
#include "pipeline/commands.h"
#include "pipeline/tree_species.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/core/lines.h"
#include "stages/core/progress.h"
#include "stages/eval/eval.h"

/* file,x,y table (the sy_label_table CSV reader with "x y" in the label column is not
 * enough: parse the three columns ourselves). */
static sy_code read_positions(const char *path, const char **files, int n, double *xy, int *have, sy_error *err)
{
    sy_buffer buf;
    sy_code rc = sy_read_file(path, &buf, err);
    if (rc) return rc;
    sy_lines L;
    sy_lines_init(&L, buf.data, buf.size);
    const char *lb, *le;
    char line[4096];
    int ln = 0;
    while (sy_lines_next(&L, &lb, &le)) {
        ln++;
        size_t len = (size_t)(le - lb) < sizeof line ? (size_t)(le - lb) : sizeof line - 1;
        memcpy(line, lb, len);
        line[len] = 0;
        char *p = line;
        while (*p == ' ') p++;
        if (*p == '#' || *p == '\n' || *p == 0) continue;
        char *c1 = strchr(p, ',');
        if (!c1) {
            rc = sy_fail(err, SY_EINPUT, "%s:%d: expected file,x,y", path, ln);
            break;
        }
        *c1 = 0;
        char *e1, *e2;
        double x = strtod(c1 + 1, &e1);
        if (e1 == c1 + 1 || *e1 != ',') {
            if (ln == 1) continue; /* a header line */
            rc = sy_fail(err, SY_EINPUT, "%s:%d: expected file,x,y", path, ln);
            break;
        }
        double y = strtod(e1 + 1, &e2);
        while (*e2 == ' ' || *e2 == '\r' || *e2 == '\n') e2++;
        if (e2 == e1 + 1 || *e2 || !isfinite(x) || !isfinite(y)) {
            rc = sy_fail(err, SY_EINPUT, "%s:%d: expected file,x,y with finite numbers", path, ln);
            break;
        }
        for (int i = 0; i < n; i++) {
            const char *b = strrchr(files[i], '/');
            if (!strcmp(files[i], p) || !strcmp(b ? b + 1 : files[i], p)) xy[2 * i] = x, xy[2 * i + 1] = y, have[i] = 1;
        }
    }
    sy_buffer_free(&buf);
    return rc;
}

int cmd_classify(int argc, char **argv, sy_cli *cli)
{
    const char *model_path = NULL, *positions_path = NULL;
    sy_vote_options vo = sy_vote_options_default();
    int no_voting = 0;
    const sy_opt opts[] = {
        {"--model", OPT_STRING, &model_path, "MODEL.sjb", "classifier (default: the species library's classifier.sjb)"},
        {"--positions", OPT_STRING, &positions_path, "CSV", "file,x,y lines: tree positions for voting (default: LAS coordinates)"},
        {"--radius", OPT_DOUBLE, &vo.radius, "M", "voting radius (default 25)"},
        {"--ratio", OPT_DOUBLE, &vo.ratio, "R", "confident iff h1 > R * h2 (default 1.5)"},
        {"--no-voting", OPT_FLAG, &no_voting, NULL, "no spatial voting: unconfident trees stay unknown"},
        {NULL, 0, NULL, NULL, NULL},
    };
    const sy_cmd_spec spec = {
        "classify", "[--model MODEL.sjb] SCANS...",
        "Classify the species of scanned trees (one tree per file).",
        "Per tree: the species (a library name, or unknown), the probability vector, whether the\n"
        "answer is confident (h1 > 1.5 h2) and whether it came from spatial voting. Positions for\n"
        "voting come from LAS coordinates (the trunk base) or --positions. Trees whose features lie\n"
        "outside the model's training range are never confident. See docs/classify.md.",
        opts, 1, -1};
    const char **pos;
    int n, rc = sy_cli_parse_all(&spec, argc, argv, cli, &pos, &n);
    if (rc) return rc < 0 ? 0 : rc;
    sy_cli_apply_settings(cli);
    vo.voting = !no_voting;
    sy_error err = {0};
    sy_jb_model m = {0};
    size_t d = sy_feature_count();
    float *x = calloc((size_t)n * d, sizeof *x);
    double *prob = calloc((size_t)n * SY_JB_MAX_CLASSES, sizeof *prob), *nov = calloc((size_t)n, sizeof *nov),
           *xy = calloc(2 * (size_t)n, sizeof *xy);
    int *have = calloc((size_t)n, sizeof *have);
    sy_tree_decision *dec = calloc((size_t)n, sizeof *dec);
    sy_scan_features_result *res = calloc((size_t)n, sizeof *res);
    if (!x || !prob || !nov || !xy || !have || !dec || !res) {
        rc = sy_fail(&err, SY_EINTERNAL, "out of memory");
        goto report;
    }
    if ((rc = sy_vote_options_check(&vo, &err))) goto report;
    char def[4200];
    const char *mp = model_path;
    if (!mp) {
        if ((rc = sy_default_model_path(def, sizeof def, &err))) goto report;
        mp = def;
    }
    if ((rc = sy_jb_load(mp, &m, &err))) goto report;
    if (m.n_features != d || m.features_version != SY_FEATURES_VERSION) {
        rc = sy_fail(&err, SY_EINPUT, "%s: trained on %zu features of version %u, this build computes %zu of version %d (retrain it)",
                     mp, m.n_features, m.features_version, d, SY_FEATURES_VERSION);
        goto report;
    }
    sy_features_options fo = sy_features_options_default();
    sy_progress bar;
    sy_progress_begin(&bar, "classify", (size_t)n);
    int quiet = sy_progress_quiet();
    sy_progress_set_quiet(1); /* one bar for the set, not one per stage and scan */
    for (int i = 0; i < n; i++) {
        if ((rc = sy_scan_features(pos[i], &fo, x + (size_t)i * d, &res[i], &err))) break;
        sy_jb_predict(&m, x + (size_t)i * d, prob + (size_t)i * m.n_classes);
        nov[i] = sy_jb_novelty(&m, x + (size_t)i * d);
        if (res[i].georeferenced) xy[2 * i] = res[i].info.base[0], xy[2 * i + 1] = res[i].info.base[1], have[i] = 1;
        sy_progress_update(&bar, (size_t)i + 1);
    }
    sy_progress_set_quiet(quiet);
    sy_progress_end(&bar);
    if (rc) goto report;
    if (positions_path && (rc = read_positions(positions_path, pos, n, xy, have, &err))) goto report;
    /* Voting needs every tree placed; trees without a position are decided alone. */
    int all = 1;
    for (int i = 0; i < n; i++) all &= have[i];
    if ((rc = sy_vote((size_t)n, m.n_classes, prob, nov, all ? xy : NULL, &vo, dec, &err))) goto report;
    if (cli->json) {
        sy_json j;
        sy_json_begin(&j, stdout, 0);
        sy_json_array(&j, NULL);
        for (int i = 0; i < n; i++) {
            sy_json_object(&j, NULL);
            sy_json_string(&j, "file", pos[i]);
            sy_json_string(&j, "species", dec[i].species >= 0 ? m.classes[dec[i].species] : "unknown");
            sy_json_object(&j, "probabilities");
            for (size_t c = 0; c < m.n_classes; c++) sy_json_number(&j, m.classes[c], prob[(size_t)i * m.n_classes + c]);
            sy_json_end(&j);
            sy_json_bool(&j, "confident", dec[i].confident);
            sy_json_bool(&j, "voted", dec[i].voted);
            sy_json_string(&j, "best", m.classes[dec[i].best]);
            sy_json_number(&j, "novelty", nov[i]);
            if (have[i]) sy_json_numbers(&j, "position", xy + 2 * i, 2);
            sy_json_int(&j, "points", (long long)res[i].info.points_in);
            sy_json_number(&j, "height", res[i].info.height);
            sy_json_end(&j);
        }
        sy_json_end(&j);
        sy_json_finish(&j);
    } else {
        for (int i = 0; i < n; i++) {
            const sy_tree_decision *t = dec + i;
            printf("%s: %s", pos[i], t->species >= 0 ? m.classes[t->species] : "unknown");
            if (t->confident) printf(" (confident, p %.2f)", t->h1);
            else if (t->voted) printf(" (voted by %d confident neighbour%s; own best %s p %.2f)", t->votes,
                                      t->votes == 1 ? "" : "s", m.classes[t->best], t->h1);
            else if (t->novel) printf(" (unlike any training tree: novelty %.2f of the threshold; best %s p %.2f)",
                                      nov[i], m.classes[t->best], t->h1);
            else printf(" (not confident: best %s p %.2f, second p %.2f)", m.classes[t->best], t->h1, t->h2);
            printf("\n ");
            /* The probability vector, largest first (at most 5). */
            int shown[SY_JB_MAX_CLASSES] = {0};
            for (int k = 0; k < 5 && k < (int)m.n_classes; k++) {
                int b = -1;
                for (size_t c = 0; c < m.n_classes; c++)
                    if (!shown[c] && (b < 0 || prob[(size_t)i * m.n_classes + c] > prob[(size_t)i * m.n_classes + b])) b = (int)c;
                shown[b] = 1;
                printf(" %s %.3f", m.classes[b], prob[(size_t)i * m.n_classes + b]);
            }
            printf("\n");
        }
    }
report:
    if (rc) rc = sy_cli_report(&err);
    sy_jb_model_free(&m);
    free(x), free(prob), free(nov), free(xy), free(have), free(dec), free(res), free(pos);
    return rc;
}
