// Writes the seed videos of fuzz_video_probe (tests/fuzz/corpus/video_probe/): 8..16 px, 1..2
// frames of MPEG-4 in MP4, MJPEG in Matroska, raw video in NUT, a few hundred bytes each (the
// Y4M, PPM and truncated seeds are written by hand). Not part of the build:
//   cc -o /tmp/gen tests/fuzz/make_video_corpus.c -lavformat -lavcodec -lavutil && /tmp/gen DIR
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <stdio.h>
#include <stdlib.h>
static int write_video(const char* path, const char* fmt, enum AVCodecID id, int pix, int w, int h, int n) {
  AVFormatContext* oc = NULL;
  if (avformat_alloc_output_context2(&oc, NULL, fmt, path) < 0) return 1;
  const AVCodec* codec = avcodec_find_encoder(id);
  if (!codec) { fprintf(stderr, "no encoder\n"); return 1; }
  AVStream* st = avformat_new_stream(oc, NULL);
  AVCodecContext* c = avcodec_alloc_context3(codec);
  c->width = w; c->height = h; c->pix_fmt = pix; c->time_base = (AVRational){1, 30};
  c->framerate = (AVRational){30, 1}; c->gop_size = 2; c->bit_rate = 20000;
  if (oc->oformat->flags & AVFMT_GLOBALHEADER) c->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
  if (avcodec_open2(c, codec, NULL) < 0) { fprintf(stderr, "open\n"); return 1; }
  avcodec_parameters_from_context(st->codecpar, c);
  st->time_base = c->time_base;
  if (avio_open(&oc->pb, path, AVIO_FLAG_WRITE) < 0) return 1;
  if (avformat_write_header(oc, NULL) < 0) return 1;
  AVFrame* f = av_frame_alloc(); f->format = pix; f->width = w; f->height = h;
  av_frame_get_buffer(f, 0);
  AVPacket* p = av_packet_alloc();
  for (int i = 0; i <= n; ++i) {
    AVFrame* in = NULL;
    if (i < n) {
      av_frame_make_writable(f);
      for (int pl = 0; pl < 3 && f->data[pl]; ++pl)
        for (int y = 0; y < (pl ? (h + 1) / 2 : h); ++y)
          for (int x = 0; x < f->linesize[pl]; ++x) f->data[pl][y * f->linesize[pl] + x] = (uint8_t)(x * 7 + y * 3 + i * 40 + pl * 50);
      f->pts = i; in = f;
    }
    avcodec_send_frame(c, in);
    while (avcodec_receive_packet(c, p) == 0) {
      av_packet_rescale_ts(p, c->time_base, st->time_base); p->stream_index = 0;
      av_interleaved_write_frame(oc, p);
    }
  }
  av_write_trailer(oc); avio_closep(&oc->pb);
  return 0;
}
int main(int argc, char** argv) {
  if (argc != 2) {
    fprintf(stderr, "usage: %s OUT_DIR\n", argv[0]);
    return 2;
  }
  const char* d = argv[1];
  char path[512];
  snprintf(path, sizeof path, "%s/mpeg4_16x16_2f.mp4", d);
  if (write_video(path, "mp4", AV_CODEC_ID_MPEG4, AV_PIX_FMT_YUV420P, 16, 16, 2)) return 1;
  snprintf(path, sizeof path, "%s/rawvideo_8x8_2f.nut", d);
  if (write_video(path, "nut", AV_CODEC_ID_RAWVIDEO, AV_PIX_FMT_YUV420P, 8, 8, 2)) return 1;
  snprintf(path, sizeof path, "%s/mjpeg_16x16_1f.mkv", d);
  if (write_video(path, "matroska", AV_CODEC_ID_MJPEG, AV_PIX_FMT_YUVJ420P, 16, 16, 1)) return 1;
  return 0;
}
