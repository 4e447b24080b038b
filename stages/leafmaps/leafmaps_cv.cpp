// OpenCV behind the leaf-maps stage (leafmaps_cv.h; image files are image_io.c). GPL-3.0-or-later.
#include "stages/leafmaps/leafmaps_cv.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <new>
#include <string>
#include <thread>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace {

// Why OpenCV threw, in one line: cv::Exception::what() ends in a newline and
// repeats the source position; its err field is the reason alone.
std::string reason_of(const std::exception_ptr &ep)
{
    try {
        std::rethrow_exception(ep);
    } catch (const cv::Exception &e) {
        return "OpenCV: " + e.err;
    } catch (const std::bad_alloc &) {
        return "out of memory";
    } catch (const std::exception &e) {
        return e.what();
    } catch (...) {
        return "unknown failure";
    }
}

sy_code cv_fail(sy_error *err, const char *what, const std::string &why)
{
    return sy_fail(err, SY_EINTERNAL, "%s: %s", what, why.c_str());
}

template <class F> sy_code guarded(sy_error *err, const char *what, F &&f)
{
    try {
        return f();
    } catch (...) {
        return cv_fail(err, what, reason_of(std::current_exception()));
    }
}

// cv::Mat headers over the caller's buffer: OpenCV writes in place unless
// the sizes or types disagree, when it would allocate a new matrix and the
// caller's buffer would stay unwritten.
sy_code in_place(const cv::Mat &d, const float *dst, sy_error *err, const char *what)
{
    if (d.data == (const unsigned char *)dst) return SY_OK;
    return sy_fail(err, SY_EINTERNAL, "%s: OpenCV did not write into the output buffer", what);
}

// Runs fn(i) for i in [0, n) on up to `threads` threads; each index runs
// exactly once, so results never depend on the thread count.
template <class F> void run_parallel(int n, int threads, F &&fn)
{
    threads = std::max(1, std::min(threads, n));
    if (threads == 1) {
        for (int i = 0; i < n; i++) fn(i);
        return;
    }
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; t++)
        pool.emplace_back([&, t] {
            for (int i = t; i < n; i += threads) fn(i);
        });
    for (auto &th : pool) th.join();
}

} // namespace

extern "C" sy_code sy_lcv_mask_clean(unsigned char *mask, int w, int h, int r, double min_frac, int max_hole,
                                     sy_error *err)
{
    return guarded(err, "mask cleanup", [&] {
        cv::Mat m(h, w, CV_8U, mask);
        if (r > 0) {
            cv::Mat disc = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1));
            cv::morphologyEx(m, m, cv::MORPH_OPEN, disc);
            cv::morphologyEx(m, m, cv::MORPH_CLOSE, disc);
        }
        cv::Mat labels, stats, centroids;
        int n = cv::connectedComponentsWithStats(m, labels, stats, centroids, 8, CV_32S);
        int largest = 0;
        for (int i = 1; i < n; i++) largest = std::max(largest, stats.at<int>(i, cv::CC_STAT_AREA));
        std::vector<unsigned char> keep((size_t)n, 0);
        for (int i = 1; i < n; i++) keep[(size_t)i] = stats.at<int>(i, cv::CC_STAT_AREA) >= min_frac * largest;
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                int l = labels.at<int>(y, x);
                mask[(size_t)y * w + x] = l > 0 && keep[(size_t)l] ? 255 : 0;
            }
        // Holes: background components that do not reach the image border.
        cv::Mat inv = 255 - m;
        n = cv::connectedComponentsWithStats(inv, labels, stats, centroids, 4, CV_32S);
        std::vector<unsigned char> fill((size_t)n, 0);
        for (int i = 1; i < n; i++) {
            int x0 = stats.at<int>(i, cv::CC_STAT_LEFT), y0 = stats.at<int>(i, cv::CC_STAT_TOP);
            int bw = stats.at<int>(i, cv::CC_STAT_WIDTH), bh = stats.at<int>(i, cv::CC_STAT_HEIGHT);
            bool border = x0 == 0 || y0 == 0 || x0 + bw == w || y0 + bh == h;
            fill[(size_t)i] = !border && stats.at<int>(i, cv::CC_STAT_AREA) <= max_hole;
        }
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++)
                if (fill[(size_t)labels.at<int>(y, x)]) mask[(size_t)y * w + x] = 255;
        return SY_OK;
    });
}

extern "C" sy_code sy_lcv_otsu(const float *v, const unsigned char *use, int w, int h, double *t, sy_error *err)
{
    return guarded(err, "Otsu threshold", [&] {
        size_t n = (size_t)w * h;
        float lo = 1e30f, hi = -1e30f;
        for (size_t i = 0; i < n; i++)
            if (!use || use[i]) {
                lo = std::min(lo, v[i]);
                hi = std::max(hi, v[i]);
            }
        if (!(hi > lo)) return sy_fail(err, SY_EINPUT, "Otsu threshold: every value is the same");
        // Otsu on a 1-D row of the selected values quantised to 16 bits.
        std::vector<unsigned char> q;
        q.reserve(n);
        for (size_t i = 0; i < n; i++)
            if (!use || use[i]) q.push_back((unsigned char)std::lround(255.0 * (v[i] - lo) / (hi - lo)));
        cv::Mat row(1, (int)q.size(), CV_8U, q.data()), dummy;
        double th = cv::threshold(row, dummy, 0, 255, cv::THRESH_BINARY | cv::THRESH_OTSU);
        *t = lo + (th + 0.5) / 255.0 * (hi - lo);
        return SY_OK;
    });
}

extern "C" sy_code sy_lcv_warp(const float *src, int w, int h, int c, const double M[6], float *dst, int dw, int dh,
                               int replicate, sy_error *err)
{
    const char *what = "warp";
    return guarded(err, what, [&] {
        cv::Mat s(h, w, CV_MAKETYPE(CV_32F, c), const_cast<float *>(src));
        cv::Mat d(dh, dw, CV_MAKETYPE(CV_32F, c), dst);
        cv::Mat A = (cv::Mat_<double>(2, 3) << M[0], M[1], M[2], M[3], M[4], M[5]);
        cv::warpAffine(s, d, A, d.size(), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                       replicate ? cv::BORDER_REPLICATE : cv::BORDER_CONSTANT, cv::Scalar::all(0));
        return in_place(d, dst, err, what);
    });
}

// ECC image alignment (Evangelidis & Psarakis 2008, "Parametric Image
// Alignment Using Enhanced Correlation Coefficient Maximization"), the
// Euclidean motion (rotation theta, shift tx, ty), on OpenCV's image
// operations and in the steps of OpenCV's findTransformECC. That one lives in
// opencv_video, which brings dnn, calib3d, features2d, flann and protobuf
// (six shared libraries) into every sylva process for this one call: a
// quarter of `sylva --version`'s start-up. Gauss-Newton on the correlation of
// the zero-mean template and warped image over the pixels the warp covers:
// each step solves for the warp increment with the Jacobian's Hessian, scaled
// by lambda so the correlation, not the squared error, is maximised.
// Returns the final correlation rho; throws cv::Exception when it cannot
// converge (lambda_d <= 0: the images are uncorrelated or do not overlap).
static double ecc_euclidean(const cv::Mat &tmpl_in, const cv::Mat &img_in, cv::Mat &warp, int iterations, double eps,
                            int gauss)
{
    const int w = tmpl_in.cols, h = tmpl_in.rows;
    cv::Mat tmpl, img, gx, gy;
    cv::GaussianBlur(tmpl_in, tmpl, cv::Size(gauss, gauss), 0, 0);
    cv::GaussianBlur(img_in, img, cv::Size(gauss, gauss), 0, 0);
    const cv::Mat dx = (cv::Mat_<float>(1, 3) << -0.5f, 0.0f, 0.5f);
    cv::filter2D(img, gx, -1, dx);
    cv::filter2D(img, gy, -1, dx.t());
    cv::Mat X(h, w, CV_32F), Y(h, w, CV_32F);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) X.at<float>(y, x) = (float)x, Y.at<float>(y, x) = (float)y;
    const cv::Mat all = cv::Mat::ones(h, w, CV_8U);
    const int flags = cv::INTER_LINEAR + cv::WARP_INVERSE_MAP, mask_flags = cv::INTER_NEAREST + cv::WARP_INVERSE_MAP;
    cv::Mat iw, gxw, gyw, mask, tzm, J[3], err;
    double rho = -1, last_rho = -eps;
    for (int it = 1; it <= iterations && std::fabs(rho - last_rho) >= eps; it++) {
        cv::warpAffine(img, iw, warp, tmpl.size(), flags);
        cv::warpAffine(gx, gxw, warp, tmpl.size(), flags);
        cv::warpAffine(gy, gyw, warp, tmpl.size(), flags);
        cv::warpAffine(all, mask, warp, tmpl.size(), mask_flags);
        cv::Scalar im, is, tm, ts;
        cv::meanStdDev(iw, im, is, mask);
        cv::meanStdDev(tmpl, tm, ts, mask);
        cv::subtract(iw, im, iw, mask);
        tzm = cv::Mat::zeros(h, w, CV_32F);
        cv::subtract(tmpl, tm, tzm, mask);
        const double covered = cv::countNonZero(mask);
        const double tmp_norm = std::sqrt(covered * ts[0] * ts[0]), img_norm = std::sqrt(covered * is[0] * is[0]);
        // The Jacobian of the warped image in theta, tx, ty.
        const float c = warp.at<float>(0, 0), s = warp.at<float>(1, 0);
        cv::Mat hat_x = -(X * s) - (Y * c), hat_y = (X * c) - (Y * s);
        J[0] = gxw.mul(hat_x) + gyw.mul(hat_y);
        J[1] = gxw;
        J[2] = gyw;
        cv::Matx33d H;
        for (int a = 0; a < 3; a++)
            for (int b = a; b < 3; b++) H(a, b) = H(b, a) = J[a].dot(J[b]);
        const cv::Matx33d Hinv = H.inv();
        const double corr = tzm.dot(iw);
        last_rho = rho;
        rho = corr / (img_norm * tmp_norm);
        if (std::isnan(rho)) CV_Error(cv::Error::StsNoConv, "ECC: NaN encountered");
        cv::Vec3d ip, tp, ep;
        for (int a = 0; a < 3; a++) ip[a] = J[a].dot(iw), tp[a] = J[a].dot(tzm);
        const cv::Vec3d iph = Hinv * ip;
        const double lambda_n = img_norm * img_norm - ip.dot(iph), lambda_d = corr - tp.dot(iph);
        if (lambda_d <= 0.0)
            CV_Error(cv::Error::StsNoConv, "ECC: the correlation would be minimised (the images are uncorrelated or "
                                           "do not overlap)");
        err = (lambda_n / lambda_d) * tzm - iw;
        for (int a = 0; a < 3; a++) ep[a] = J[a].dot(err);
        const cv::Vec3d dp = Hinv * ep;
        const double theta = dp[0] + std::asin(warp.at<float>(1, 0));
        warp.at<float>(0, 2) += (float)dp[1];
        warp.at<float>(1, 2) += (float)dp[2];
        warp.at<float>(0, 0) = warp.at<float>(1, 1) = (float)std::cos(theta);
        warp.at<float>(1, 0) = (float)std::sin(theta);
        warp.at<float>(0, 1) = -warp.at<float>(1, 0);
    }
    return rho;
}

extern "C" sy_code sy_lcv_register(const float *ref, const float *mov, int w, int h, double M[6], sy_error *err)
{
    return guarded(err, "ECC registration", [&] {
        cv::Mat r(h, w, CV_32F, const_cast<float *>(ref)), m(h, w, CV_32F, const_cast<float *>(mov));
        cv::Mat warp = (cv::Mat_<float>(2, 3) << (float)M[0], (float)M[1], (float)M[2], (float)M[3], (float)M[4],
                        (float)M[5]);
        ecc_euclidean(r, m, warp, 100, 1e-6, 5);
        for (int i = 0; i < 6; i++) M[i] = warp.at<float>(i / 3, i % 3);
        return SY_OK;
    });
}

extern "C" sy_code sy_lcv_blur(const float *src, int w, int h, int c, double sigma, float *dst, sy_error *err)
{
    const char *what = "blur";
    return guarded(err, what, [&] {
        cv::Mat s(h, w, CV_MAKETYPE(CV_32F, c), const_cast<float *>(src));
        cv::Mat d(h, w, CV_MAKETYPE(CV_32F, c), dst);
        cv::GaussianBlur(s, d, cv::Size(0, 0), sigma, sigma, cv::BORDER_REPLICATE);
        return in_place(d, dst, err, what);
    });
}

extern "C" sy_code sy_lcv_resize(const float *src, int w, int h, int c, float *dst, int dw, int dh, sy_error *err)
{
    const char *what = "resize";
    return guarded(err, what, [&] {
        cv::Mat s(h, w, CV_MAKETYPE(CV_32F, c), const_cast<float *>(src));
        cv::Mat d(dh, dw, CV_MAKETYPE(CV_32F, c), dst);
        cv::resize(s, d, d.size(), 0, 0, dw <= w && dh <= h ? cv::INTER_AREA : cv::INTER_LINEAR);
        return in_place(d, dst, err, what);
    });
}

extern "C" sy_code sy_lcv_convolve_sum(const float *const *in, int n_out, int n_k, const float *const *kernel,
                                       int r, int w, int h, float *const *out, int threads, sy_error *err)
{
    const char *what = "FFT convolution";
    return guarded(err, what, [&] {
        int pw = cv::getOptimalDFTSize(w + 2 * r), ph = cv::getOptimalDFTSize(h + 2 * r);
        int ks = 2 * r + 1;
        std::vector<cv::Mat> kspec((size_t)n_k);
        // The first worker to fail keeps its reason; the others only stop.
        std::mutex first_lock;
        std::exception_ptr first;
        auto keep = [&] {
            std::lock_guard<std::mutex> lock(first_lock);
            if (!first) first = std::current_exception();
        };
        // Kernels wrapped around the origin so the product gives 'same' output.
        run_parallel(n_k, threads, [&](int k) {
            try {
                cv::Mat z = cv::Mat::zeros(ph, pw, CV_32F);
                for (int dy = -r; dy <= r; dy++)
                    for (int dx = -r; dx <= r; dx++)
                        z.at<float>((dy + ph) % ph, (dx + pw) % pw) = kernel[k][(size_t)(dy + r) * ks + (dx + r)];
                cv::dft(z, kspec[(size_t)k], 0, ks);
            } catch (...) {
                keep();
            }
        });
        if (first) return cv_fail(err, what, reason_of(first));
        run_parallel(n_out, threads, [&](int i) {
            try {
                cv::Mat acc = cv::Mat::zeros(ph, pw, CV_32F), spec, prod;
                cv::Mat z = cv::Mat::zeros(ph, pw, CV_32F);
                for (int k = 0; k < n_k; k++) {
                    cv::Mat src(h, w, CV_32F, const_cast<float *>(in[(size_t)i * n_k + k]));
                    src.copyTo(z(cv::Rect(0, 0, w, h)));
                    cv::dft(z, spec, 0, h);
                    cv::mulSpectrums(spec, kspec[(size_t)k], prod, 0);
                    acc += prod;
                }
                cv::Mat res;
                cv::dft(acc, res, cv::DFT_INVERSE | cv::DFT_SCALE | cv::DFT_REAL_OUTPUT, h);
                for (int y = 0; y < h; y++)
                    std::memcpy(out[i] + (size_t)y * w, res.ptr<float>(y), (size_t)w * sizeof(float));
            } catch (...) {
                keep();
            }
        });
        return first ? cv_fail(err, what, reason_of(first)) : SY_OK;
    });
}
