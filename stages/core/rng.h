/* splitmix64 (Steele, Lea & Flood 2014, "Fast splittable pseudorandom number
 * generators"): the one random source of every stage. Tiny, seedable, the
 * same numbers on every platform; header-only so each stage inlines it. */
#ifndef SYLVA_RNG_H
#define SYLVA_RNG_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define SY_GOLDEN_GAMMA 0x9E3779B97F4A7C15ull

/* The splitmix64 output function of z + the golden gamma: a stateless hash
 * for counter-based streams (draw k of pulse p = sy_mix64(key ^ ...)). */
static inline uint64_t sy_mix64(uint64_t z)
{
    z += SY_GOLDEN_GAMMA;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/* The next number of the sequential generator whose state is *state. */
static inline uint64_t sy_splitmix64(uint64_t *state)
{
    uint64_t z = sy_mix64(*state);
    *state += SY_GOLDEN_GAMMA;
    return z;
}

/* Uniform double in [0, 1) from the top 53 bits of x. */
static inline double sy_unit53(uint64_t x) { return (double)(x >> 11) * (1.0 / 9007199254740992.0); }

/* perm = a Fisher–Yates shuffle of 0..n-1 drawn from the generator at *state
 * (which it advances): the one seeded permutation of the stages. */
static inline void sy_permutation(uint32_t *perm, size_t n, uint64_t *state)
{
    for (size_t i = 0; i < n; i++) perm[i] = (uint32_t)i;
    for (size_t i = n; i > 1; i--) {
        size_t j = (size_t)(sy_splitmix64(state) % i);
        uint32_t t = perm[i - 1];
        perm[i - 1] = perm[j];
        perm[j] = t;
    }
}

#ifdef __cplusplus
}
#endif

#endif
