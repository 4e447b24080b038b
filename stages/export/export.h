/* Export: Asset -> glTF 2.0 binary (.glb) bytes; the caller writes them
 * (atomically: sy_write_file_atomic). */
#ifndef SYLVA_EXPORT_H
#define SYLVA_EXPORT_H

#include <stddef.h>

#include "stages/core/asset.h"

#ifdef __cplusplus
extern "C" {
#ifdef __cplusplus
}
#endif

#endif

typedef struct {
    int meshopt;         /* EXT_meshopt_compression with meshoptimizer's codec */
    int instancing;      /* EXT_mesh_gpu_instancing for leaves (default 1); 0 bakes instances */
    const char *generator; /* asset.generator, default "Sylva <version>" */
} sy_export_options;

sy_export_options sy_export_options_default(void);

/* SY_EUSAGE naming the field when a flag is not 0/1 or generator too long. */
sy_code sy_export_options_check(const sy_export_options *o, sy_error *err);

/* Checks the asset and serialises it: *glb (malloc'd, the caller frees) and
 * *size. name names the output in messages ("tree.glb"; NULL: "glb").
 * opt NULL: the defaults. A malformed asset fails with SY_EINPUT naming the
 * mesh, material or level; on failure *glb is NULL. */
sy_code sy_export_glb(const sy_asset *asset, const sy_export_options *opt, const char *name, unsigned char **glb,
                      size_t *size, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
