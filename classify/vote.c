/* The decision per tree and spatial voting (Pirk 2013 §3.5.1): a JointBoost
 * answer is confident iff h1 > 1.5 h2 (h1, h2 the highest and second-highest
 * probabilities). Trees in a city are planted in same-species groups, so an
 * unconfident tree looks at the confident trees within 25 m: their answers form
 * the set of possible species and the candidate this tree itself finds most
 * probable is chosen. In mixed stands voting hurts (the thesis: 95.5% -> 89%),
 * hence the switch. A tree whose features lie outside what the model was
 * trained on (the joint novelty test, novelty.c) is never confident: it is how a house comes out
 * unknown rather than as its nearest species. */
#include <math.h>
#include <string.h>

#include "classify/classify.h"

sy_vote_options sy_vote_options_default(void)
{
    sy_vote_options o = {1.5, 25.0, 1, 1.0};
    return o;
}

sy_code sy_vote_options_check(const sy_vote_options *o, sy_error *err)
{
    if (!(o->ratio >= 1 && isfinite(o->ratio))) return sy_fail(err, SY_EUSAGE, "vote: ratio must be a finite number >= 1");
    if (!(o->radius >= 0 && o->radius < 1e7)) return sy_fail(err, SY_EUSAGE, "vote: radius must be >= 0 metres");
    if (!(o->novelty_max > 0 && o->novelty_max < 1e6)) return sy_fail(err, SY_EUSAGE, "vote: novelty_max must be > 0");
    return SY_OK;
}

sy_code sy_vote(size_t n, size_t C, const double *prob, const double *novelty, const double *xy,
                const sy_vote_options *o, sy_tree_decision *out, sy_error *err)
{
    sy_code rc = sy_vote_options_check(o, err);
    if (rc) return rc;
    if (C < 1 || C > SY_JB_MAX_CLASSES) return sy_fail(err, SY_EINPUT, "vote: %zu classes", C);
    for (size_t i = 0; i < n; i++) {
        const double *p = prob + i * C;
        sy_tree_decision *d = out + i;
        memset(d, 0, sizeof *d);
        size_t b1 = 0;
        for (size_t c = 1; c < C; c++)
            if (p[c] > p[b1]) b1 = c;
        double h2 = 0;
        for (size_t c = 0; c < C; c++)
            if (c != b1 && p[c] > h2) h2 = p[c];
        d->best = (int)b1;
        d->h1 = p[b1];
        d->h2 = h2;
        d->novel = novelty && novelty[i] > o->novelty_max;
        d->confident = !d->novel && p[b1] > o->ratio * h2;
        d->species = d->confident ? (int)b1 : -1;
    }
    if (!xy || !o->voting) return SY_OK;
    double r2 = o->radius * o->radius;
    for (size_t i = 0; i < n; i++) {
        sy_tree_decision *d = out + i;
        if (d->confident || d->novel) continue; /* a house takes no vote from the trees around it */
        int votes[SY_JB_MAX_CLASSES] = {0};
        int any = 0;
        for (size_t j = 0; j < n; j++) {
            if (j == i || !out[j].confident) continue;
            double dx = xy[2 * j] - xy[2 * i], dy = xy[2 * j + 1] - xy[2 * i + 1];
            if (dx * dx + dy * dy > r2) continue;
            votes[out[j].best]++;
            any = 1;
        }
        if (!any) continue;
        const double *p = prob + i * C;
        int pick = -1;
        for (size_t c = 0; c < C; c++) {
            if (!votes[c]) continue;
            if (pick < 0 || p[c] > p[pick] || (p[c] == p[pick] && votes[c] > votes[pick])) pick = (int)c;
        }
        d->species = pick;
        d->voted = 1;
        d->votes = votes[pick];
    }
    return SY_OK;
}
