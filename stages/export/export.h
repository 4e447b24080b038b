/* Export: Asset -> glTF 2.0 binary (.glb), written atomically. */
#ifndef SYLVA_EXPORT_H
#define SYLVA_EXPORT_H

#include "stages/core/asset.h"

typedef struct {
    int meshopt;         /* EXT_meshopt_compression with meshoptimizer's codec */
    int instancing;      /* EXT_mesh_gpu_instancing for leaves (default 1); 0 bakes instances */
    const char *generator; /* asset.generator, default "Sylva <version>" */
} sy_export_options;

sy_export_options sy_export_options_default(void);

sy_code sy_export_glb(const char *path, const sy_asset *asset, const sy_export_options *opt, sy_error *err);

/* Size in bytes of the last successful export to path (for reports), or 0. */
size_t sy_export_last_size(const char *path);

#endif
