/* LAS layout facts shared by the reader (las.c) and writer (las_write.c):
 * header field offsets, point record layouts and little-endian byte access.
 * Byte-wise decoding keeps the code independent of host endianness and
 * alignment; compilers turn these into single loads on x86/ARM. */
#ifndef SYLVA_LAS_FORMAT_H
#define SYLVA_LAS_FORMAT_H

#include <stdint.h>
#include <string.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Header field offsets (LAS 1.0-1.4). */
enum {
    LAS_HDR_MIN = 227,        /* LAS 1.0-1.2 header size */
    LAS_HDR_14 = 375,         /* LAS 1.4 header size */
    LAS_VERSION_MAJOR = 24,
    LAS_VERSION_MINOR = 25,
    LAS_SYSTEM_ID = 26,
    LAS_SOFTWARE = 58,
    LAS_CREATION_DAY = 90,
    LAS_CREATION_YEAR = 92,
    LAS_HEADER_SIZE = 94,
    LAS_POINT_OFFSET = 96,
    LAS_N_VLRS = 100,
    LAS_POINT_FORMAT = 104,
    LAS_RECORD_LENGTH = 105,
    LAS_LEGACY_COUNT = 107,
    LAS_LEGACY_BY_RETURN = 111, /* 5 x u32 */
    LAS_SCALE = 131,
    LAS_OFFSET = 155,
    LAS_BOUNDS = 179,         /* max x, min x, max y, min y, max z, min z */
    LAS_EVLR_START = 235,     /* 1.4 */
    LAS_N_EVLRS = 243,        /* 1.4 */
    LAS_COUNT64 = 247,        /* 1.4 */
    LAS_BY_RETURN64 = 255,    /* 1.4: 15 x u64 */
    LAS_VLR_HEADER = 54,
    LAS_EVLR_HEADER = 60,
    LAS_EB_DESCRIPTOR = 192,  /* one extra-bytes descriptor */
    LAS_MAX_FORMAT = 10,
    LAS_GLOBAL_GPS_STANDARD = 1 << 0, /* global encoding bit: adjusted standard GPS time */
    LAS_GLOBAL_WKT = 1 << 4,  /* global encoding bit: CRS is WKT */
};

/* Extra-bytes descriptor field offsets and option bits (LAS 1.4 R15 table 24). */
enum {
    LAS_EB_TYPE = 2,
    LAS_EB_OPTIONS = 3,
    LAS_EB_NAME = 4,
    LAS_EB_NO_DATA = 40,
    LAS_EB_MIN = 64,
    LAS_EB_MAX = 88,
    LAS_EB_SCALE = 112,
    LAS_EB_OFFSET = 136,
    LAS_EB_DESCRIPTION = 160,
    LAS_EB_OPT_NO_DATA = 1 << 0,
    LAS_EB_OPT_MIN = 1 << 1,
    LAS_EB_OPT_MAX = 1 << 2,
    LAS_EB_OPT_SCALE = 1 << 3,
    LAS_EB_OPT_OFFSET = 1 << 4,
    LAS_EB_INT32 = 6,
    LAS_EB_FLOAT = 9,
    LAS_EB_DOUBLE = 10,
};

/* Extra-bytes names that carry normals (PDAL's dimension names), x, y, z. */
static const char *const las_normal_names[3] = {"NormalX", "NormalY", "NormalZ"};

/* Where the optional fields sit in a point record of each format; -1 when
 * the format lacks the field. Formats 0-5 pack returns in 3-bit fields and
 * classification in 5 bits; formats 6-10 use 4-bit returns and a full byte. */
typedef struct {
    unsigned short size;
    signed char gps, rgb, nir;
} las_layout;

static const las_layout las_layouts[LAS_MAX_FORMAT + 1] = {
    {20, -1, -1, -1}, {28, 20, -1, -1}, {26, -1, 20, -1}, {34, 20, 28, -1},
    {57, 20, -1, -1}, {63, 20, 28, -1}, {30, 22, -1, -1}, {36, 22, 30, -1},
    {38, 22, 30, 36}, {59, 22, -1, -1}, {67, 22, 30, 36},
};

static inline uint16_t las_u16(const unsigned char *p) { return (uint16_t)(p[0] | (unsigned)p[1] << 8); }
static inline uint32_t las_u32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static inline uint64_t las_u64(const unsigned char *p) { return las_u32(p) | (uint64_t)las_u32(p + 4) << 32; }
static inline int32_t las_i32(const unsigned char *p) { return (int32_t)las_u32(p); }
static inline double las_f64(const unsigned char *p)
{
    uint64_t u = las_u64(p);
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}
static inline float las_f32(const unsigned char *p)
{
    uint32_t u = las_u32(p);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static inline void las_put_u16(unsigned char *p, uint16_t v)
{
    p[0] = (unsigned char)v;
    p[1] = (unsigned char)(v >> 8);
}
static inline void las_put_u32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(v >> (8 * i));
}
static inline void las_put_u64(unsigned char *p, uint64_t v)
{
    for (int i = 0; i < 8; i++) p[i] = (unsigned char)(v >> (8 * i));
}
static inline void las_put_f32(unsigned char *p, float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    las_put_u32(p, u);
}
static inline void las_put_f64(unsigned char *p, double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    las_put_u64(p, u);
}

#ifdef __cplusplus
}
#endif

#endif
