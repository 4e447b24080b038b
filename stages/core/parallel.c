#include "parallel.h"

#include <pthread.h>
#include <unistd.h>

static int g_threads;

void sy_set_threads(int n) { g_threads = n; }

int sy_threads(void)
{
    if (g_threads > 0) return g_threads;
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n > 0 ? (int)n : 1;
}

typedef struct {
    size_t n, chunk_size, n_chunks, next;
    pthread_mutex_t lock;
    void (*fn)(void *, size_t, size_t, size_t);
    void *ctx;
} job;

static void *worker(void *arg)
{
    job *j = arg;
    for (;;) {
        pthread_mutex_lock(&j->lock);
        size_t c = j->next++;
        pthread_mutex_unlock(&j->lock);
        if (c >= j->n_chunks) return NULL;
        size_t b = c * j->chunk_size, e = b + j->chunk_size;
        j->fn(j->ctx, b, e > j->n ? j->n : e, c);
    }
}

void sy_parallel_for(size_t n, size_t chunk_size, void (*fn)(void *, size_t, size_t, size_t), void *ctx)
{
    if (chunk_size == 0) chunk_size = 1;
    job j = {n, chunk_size, (n + chunk_size - 1) / chunk_size, 0, PTHREAD_MUTEX_INITIALIZER, fn, ctx};
    int t = sy_threads();
    if ((size_t)t > j.n_chunks) t = (int)j.n_chunks;
    pthread_t tids[64];
    if (t > 64) t = 64;
    int started = 0;
    for (int i = 1; i < t; i++)
        if (pthread_create(&tids[started], NULL, worker, &j) == 0) started++;
    worker(&j);
    for (int i = 0; i < started; i++) pthread_join(tids[i], NULL);
    pthread_mutex_destroy(&j.lock);
}
