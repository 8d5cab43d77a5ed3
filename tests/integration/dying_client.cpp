// tessera-test-dying-client: a client that gets half-way through a call and then waits to be
// killed (SIGKILL), so tests can check what the server does when a client process dies: the
// connection drops without a gRPC cancel or half-close.
//
//   tessera-test-dying-client ADDRESS stream   opens a Stream, reads one frame, prints "ready"
//   tessera-test-dying-client ADDRESS upload   sends a manifest declaring 8 MiB and one 1 MiB
//                                              chunk, prints "ready"
// Then it sleeps until killed.
#include <grpcpp/grpcpp.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <string>

#include "tessera/v1/render_service.grpc.pb.h"

namespace v1 = tessera::v1;

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s ADDRESS stream|upload\n", argv[0]);
    return 2;
  }
  auto stub = v1::RenderService::NewStub(
      grpc::CreateChannel(argv[1], grpc::InsecureChannelCredentials()));
  grpc::ClientContext ctx;
  if (std::strcmp(argv[2], "stream") == 0) {
    auto rw = stub->Stream(&ctx);
    v1::ClientEvent open;
    open.mutable_open()->set_scene_id("demo");
    open.mutable_open()->mutable_settings()->set_width(64);
    open.mutable_open()->mutable_settings()->set_height(48);
    open.mutable_open()->set_target_fps(30.0f);
    v1::Frame frame;
    if (!rw->Write(open) || !rw->Read(&frame)) return 1;
    // Keep frames coming so the server has some in flight when the process dies.
    std::printf("ready %s\n", frame.session_token().c_str());
  } else if (std::strcmp(argv[2], "upload") == 0) {
    v1::SceneInfo info;
    auto writer = stub->UploadScene(&ctx, &info);
    v1::UploadRequest manifest;
    v1::UploadFile* file = manifest.mutable_manifest()->add_files();
    file->set_name("big.glb");
    file->set_size(8u << 20);
    v1::UploadRequest chunk;
    chunk.mutable_chunk()->set_file_index(0);
    chunk.mutable_chunk()->set_offset(0);
    chunk.mutable_chunk()->set_data(std::string(1u << 20, 'x'));
    if (!writer->Write(manifest) || !writer->Write(chunk)) return 1;
    std::printf("ready\n");
  } else {
    std::fprintf(stderr, "unknown mode %s\n", argv[2]);
    return 2;
  }
  std::fflush(stdout);
  for (;;) pause();
}
