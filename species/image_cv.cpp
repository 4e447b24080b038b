// OpenCV shim for species materials (see image_cv.h). All OpenCV use of the
// species code lives here.
#include "species/image_cv.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <cstdlib>

#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgproc.hpp>

namespace {
// OpenCV logs [ WARN ]/[ERROR] lines of its own on stderr; Sylva turns every
// failure into one line itself. OpenCV reads OPENCV_LOG_LEVEL while loading,
// before main could set it, so the level is set here at static-init time
// (which runs after libopencv_core's), unless the user asked for one.
struct QuietOpenCv {
    QuietOpenCv()
    {
        if (!std::getenv("OPENCV_LOG_LEVEL")) cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
    }
} quiet_opencv;
} // namespace

sy_code sy_cv_resize_rgba(const unsigned char *src, int w, int h, unsigned char *dst, int dw, int dh,
                          sy_error *err)
{
    try {
        cv::Mat in(h, w, CV_8UC4, const_cast<unsigned char *>(src));
        cv::Mat f;
        in.convertTo(f, CV_32FC4, 1.0 / 255.0);
        // Premultiply, resize, un-premultiply: edges keep the leaf's colour.
        std::vector<cv::Mat> ch;
        cv::split(f, ch);
        for (int c = 0; c < 3; c++) ch[c] = ch[c].mul(ch[3]);
        cv::merge(ch, f);
        cv::Mat small;
        cv::resize(f, small, cv::Size(dw, dh), 0, 0, (dw < w || dh < h) ? cv::INTER_AREA : cv::INTER_LINEAR);
        cv::split(small, ch);
        cv::Mat a = cv::max(ch[3], 1e-6);
        for (int c = 0; c < 3; c++) ch[c] = cv::min(ch[c] / a, 1.0);
        cv::merge(ch, small);
        cv::Mat out(dh, dw, CV_8UC4, dst);
        small.convertTo(out, CV_8UC4, 255.0);
        return SY_OK;
    } catch (const cv::Exception &e) {
        return sy_fail(err, SY_EINTERNAL, "%s: OpenCV: %s", "resize", e.what());
    }
}

sy_code sy_cv_normal_map(const unsigned char *rgba, int w, int h, float strength, int wrap, unsigned char *rgb,
                         sy_error *err)
{
    try {
        cv::Mat in(h, w, CV_8UC4, const_cast<unsigned char *>(rgba));
        cv::Mat gray, height;
        cv::cvtColor(in, gray, cv::COLOR_RGBA2GRAY);
        gray.convertTo(height, CV_32F, 1.0 / 255.0);
        // Sobel cannot wrap by itself: pad by one texel from the other side.
        cv::Mat padded;
        cv::copyMakeBorder(height, padded, 1, 1, 1, 1, wrap ? cv::BORDER_WRAP : cv::BORDER_REPLICATE);
        cv::Mat gx, gy;
        cv::Sobel(padded, gx, CV_32F, 1, 0, 3, 1.0 / 8.0); // per-texel slope
        cv::Sobel(padded, gy, CV_32F, 0, 1, 3, 1.0 / 8.0); // +rows = down the image
        cv::Rect inner(1, 1, w, h);
        gx = gx(inner);
        gy = gy(inner);
        for (int y = 0; y < h; y++) {
            const float *px = gx.ptr<float>(y), *py = gy.ptr<float>(y);
            unsigned char *o = rgb + (size_t)y * (size_t)w * 3;
            for (int x = 0; x < w; x++) {
                // dh/dy_up = -dh/drow, so n_y = +s * dh/drow.
                float nx = -strength * px[x], ny = strength * py[x], nz = 1.0f;
                float len = std::sqrt(nx * nx + ny * ny + nz * nz);
                float n[3] = {nx / len, ny / len, nz / len};
                for (int c = 0; c < 3; c++) {
                    float v = (n[c] * 0.5f + 0.5f) * 255.0f + 0.5f;
                    o[3 * x + c] = (unsigned char)std::min(255.0f, std::max(0.0f, v));
                }
            }
        }
        return SY_OK;
    } catch (const cv::Exception &e) {
        return sy_fail(err, SY_EINTERNAL, "%s: OpenCV: %s", "normal map", e.what());
    }
}

sy_code sy_cv_alpha_from_background(unsigned char *rgba, int w, int h, float threshold, sy_error *err)
{
    try {
        cv::Mat img(h, w, CV_8UC4, rgba);
        // Background colour: per-channel median of the border pixels.
        std::vector<unsigned char> border[3];
        for (int x = 0; x < w; x++)
            for (int y : {0, h - 1})
                for (int c = 0; c < 3; c++) border[c].push_back(img.at<cv::Vec4b>(y, x)[c]);
        for (int y = 0; y < h; y++)
            for (int x : {0, w - 1})
                for (int c = 0; c < 3; c++) border[c].push_back(img.at<cv::Vec4b>(y, x)[c]);
        float bg[3];
        for (int c = 0; c < 3; c++) {
            auto mid = border[c].begin() + (long)(border[c].size() / 2);
            std::nth_element(border[c].begin(), mid, border[c].end());
            bg[c] = *mid;
        }
        cv::Mat mask(h, w, CV_8U);
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                const cv::Vec4b &p = img.at<cv::Vec4b>(y, x);
                float d2 = 0;
                for (int c = 0; c < 3; c++) d2 += (p[c] - bg[c]) * (p[c] - bg[c]);
                mask.at<unsigned char>(y, x) = d2 > threshold * threshold ? 255 : 0;
            }
        cv::medianBlur(mask, mask, 3); // drop speckles from photo noise
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) img.at<cv::Vec4b>(y, x)[3] = mask.at<unsigned char>(y, x);
        return SY_OK;
    } catch (const cv::Exception &e) {
        return sy_fail(err, SY_EINTERNAL, "%s: OpenCV: %s", "alpha extraction", e.what());
    }
}
