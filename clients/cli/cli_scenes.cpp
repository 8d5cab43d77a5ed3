// tessera info | scenes | rm: the small unary calls.
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/match.h"
#include "absl/strings/str_join.h"
#include "clients/cli/cli_commands.h"
#include "clients/cli/cli_format.h"
#include "google/protobuf/descriptor.h"
#include "google/protobuf/message.h"

namespace tessera::cli {
namespace {

// Commands without options still reject stray words, so typos do not pass silently.
void NoArguments(const Invocation& inv) {
  ArgReader args(inv);
  if (args.Next()) args.Unknown();
}

std::string JoinNumbers(const google::protobuf::RepeatedField<uint32_t>& v) {
  return absl::StrJoin(v, "|");
}

// "json_bytes 64.0 MiB, json_depth 64, nodes 262144, ..." in the proto's field order.
std::string ImportLimitsSummary(const v1::ImportLimits& limits) {
  const google::protobuf::Descriptor* d = limits.GetDescriptor();
  const google::protobuf::Reflection* r = limits.GetReflection();
  std::vector<std::string> items;
  for (int i = 0; i < d->field_count(); ++i) {
    const google::protobuf::FieldDescriptor* f = d->field(i);
    const uint64_t v = f->cpp_type() == google::protobuf::FieldDescriptor::CPPTYPE_UINT64
                           ? r->GetUInt64(limits, f)
                           : r->GetUInt32(limits, f);
    std::string name = f->name();
    if (absl::StartsWith(name, "max_")) name = name.substr(4);
    items.push_back(absl::StrCat(name, " ", absl::EndsWith(name, "_bytes") ? HumanBytes(v)
                                                                            : absl::StrCat(v)));
  }
  return absl::StrJoin(items, ", ");
}

void PrintServerInfo(const Invocation& inv, const v1::ServerInfo& info) {
  const v1::DeviceDescription& d = info.device();
  const v1::Limits& l = info.limits();
  const v1::SettingChoices& c = info.choices();
  absl::PrintF("server     %s: tesserad %s, up %s\n", inv.global.server, info.version(),
               HumanDuration(info.uptime_s()));
  absl::PrintF("device     %s (%s)\n", d.name(), d.type());
  absl::PrintF("driver     %s%s, Vulkan %s\n", d.driver_name(),
               d.driver_info().empty() ? "" : ", " + d.driver_info(), d.api_version());
  absl::PrintF("health     %s; %s\n",
               info.serving() ? std::string("SERVING") : "NOT_SERVING: " + info.unhealthy_reason(),
               info.accepting_sessions() ? "taking new sessions"
                                         : "not taking new sessions (readiness NOT_SERVING)");
  absl::PrintF("scenes     %s\n", info.scene_store()
                                       ? "shared with other replicas (--scene_store_dir)"
                                       : "this server's own (no shared scene store)");
  for (const v1::DeviceFallback& f : d.fallbacks())
    absl::PrintF("fallback   no %s: %s\n", f.missing(), f.path());
  absl::PrintF(
      "load       %u scenes (%s on the device), %u sessions (+%u parked), queue depth %u "
      "(%u background), %u frames in flight, %u frames rendered\n",
      info.scenes_loaded(), HumanBytes(info.scene_device_bytes()), info.active_sessions(),
      info.parked_sessions(), info.queue_depth(), info.background_queue_depth(),
      info.frames_in_flight(), info.frames_rendered());
  absl::PrintF(
      "limits     %ux MSAA, frames up to %ux%u, %u scenes, %u sessions, %u synthetic lights\n",
      l.max_samples(), l.max_width(), l.max_height(), l.max_scenes(), l.max_sessions(),
      l.max_synthetic_lights());
  absl::PrintF("streams    up to %g fps each, resumable for %u s, %u frames encoding at once\n",
               l.max_session_fps(), l.resume_grace_s(), l.max_frames_in_flight());
  absl::PrintF("memory     %s on the device in all, up to %s per scene\n",
               HumanBytes(info.device_memory_bytes()),
               l.max_scene_device_bytes() != 0 ? HumanBytes(l.max_scene_device_bytes())
                                               : std::string("any size"));
  if (l.scene_memory_budget_bytes() != 0)
    absl::PrintF("memory     %s for uploaded scenes (unused ones evicted, least recently used "
                 "first)\n",
                 HumanBytes(l.scene_memory_budget_bytes()));
  absl::PrintF("jobs       %u active, up to %u kept and %u frames each, %s, %s\n",
               info.jobs_active(), l.max_jobs(), l.max_job_frames(),
               info.jobs_persistent() ? "resumed after a restart (--state_dir)"
                                      : "not kept over a restart",
               info.job_output_root() ? "server-side output on" : "no server-side output");
  absl::PrintF("security   %s, %s\n", info.tls() ? "TLS" : "plaintext",
               info.auth_required() ? "bearer tokens required" : "no tokens");
  absl::PrintF("uploads    up to %s in %u files, chunks up to %s\n",
               HumanBytes(l.max_upload_bytes()), l.max_upload_files(),
               HumanBytes(l.max_chunk_bytes()));
  absl::PrintF("assets     %s\n", WrapList(ImportLimitsSummary(l.scene_import()), 11));
  absl::PrintF("glTF       %s\n", WrapList(absl::StrJoin(info.gltf_extensions(), ", "), 11));
  absl::PrintF("video      jpeg, h264 (%s)\n", absl::StrJoin(info.video_encoders(), ", "));
  absl::PrintF("choices    aa        %s\n", absl::StrJoin(c.aa(), "|"));
  absl::PrintF("           samples   %s\n", JoinNumbers(c.samples()));
  absl::PrintF("           culling   %s\n", absl::StrJoin(c.culling(), "|"));
  absl::PrintF("           exposure  %s\n", absl::StrJoin(c.exposure_mode(), "|"));
  absl::PrintF("           tonemapper %s\n", absl::StrJoin(c.tonemapper(), "|"));
  absl::PrintF("           debug     %s\n", absl::StrJoin(c.debug_view(), "|"));
  absl::PrintF("           tile      %s\n", JoinNumbers(c.tile_size()));
  absl::PrintF("defaults   %s\n", WrapList(SettingsSummary(info.default_settings()), 11));
}

int RunInfo(const Invocation& inv) {
  NoArguments(inv);
  auto stub = ConnectStub(inv);
  if (!stub) return kExitError;
  grpc::ClientContext context;
  SetDeadline(&context, kShortCallSeconds);
  v1::ServerInfo info;
  grpc::Status status = stub->GetServerInfo(&context, v1::GetServerInfoRequest(), &info);
  if (!status.ok()) return ReportRpcError(inv, status);
  if (inv.global.json) {
    Json j = ToJson(info);
    j["server"] = inv.global.server;
    PrintJson(j);
  } else {
    PrintServerInfo(inv, info);
  }
  return 0;
}

void PrintSceneTable(const v1::ListScenesResponse& list) {
  absl::PrintF("%-12s  %-24s  %12s  %10s  %8s  %s\n", "ID", "NAME", "TRIANGLES", "DEVICE MiB",
               "SESSIONS", "DELETED");
  for (const v1::SceneInfo& s : list.scenes()) {
    std::string name = s.name();
    // Long names would push the numbers out of their columns.
    if (name.size() > 24) name = name.substr(0, 21) + "...";
    absl::PrintF("%-12s  %-24s  %12u  %10.1f  %8u  %s\n", s.scene_id().substr(0, 12), name,
                 s.counts().triangles(), s.device_bytes() / (1024.0 * 1024.0), s.sessions(),
                 s.deleted() ? "yes" : "");
  }
}

int RunScenes(const Invocation& inv) {
  NoArguments(inv);
  auto stub = ConnectStub(inv);
  if (!stub) return kExitError;
  grpc::ClientContext context;
  SetDeadline(&context, kShortCallSeconds);
  v1::ListScenesResponse list;
  grpc::Status status = stub->ListScenes(&context, v1::ListScenesRequest(), &list);
  if (!status.ok()) return ReportRpcError(inv, status);
  if (inv.global.json) {
    PrintJson(ToJson(list));
  } else {
    PrintSceneTable(list);
  }
  return 0;
}

int RunRm(const Invocation& inv) {
  std::vector<std::string> ids;
  ArgReader args(inv);
  while (args.Next()) {
    if (!args.IsPositional()) args.Unknown();
    ids.push_back(args.current());
  }
  if (ids.empty()) args.Fail("which scene? give one or more scene ids");
  auto stub = ConnectStub(inv);
  if (!stub) return kExitError;

  Json out = Json::array();
  int rc = 0;
  for (const std::string& id : ids) {
    std::string full_id;
    grpc::Status status = ResolveSceneId(stub.get(), id, &full_id);
    v1::DeleteSceneResponse response;
    if (status.ok()) {
      grpc::ClientContext context;
      SetDeadline(&context, kShortCallSeconds);
      v1::DeleteSceneRequest request;
      request.set_scene_id(full_id);
      status = stub->DeleteScene(&context, request, &response);
    }
    if (!status.ok()) {
      // Go on with the other ids: each one is independent.
      rc = ReportRpcError(inv, status);
      if (inv.global.json) out.push_back({{"scene_id", id}, {"error", ErrorJson(status)}});
      continue;
    }
    const uint32_t still = response.sessions_still_using();
    if (inv.global.json) {
      out.push_back({{"scene_id", full_id}, {"sessions_still_using", still}});
    } else if (still == 0) {
      absl::PrintF("deleted %s\n", full_id);
    } else {
      absl::PrintF("deleted %s; %s still use%s it (freed when %s)\n", full_id,
                   still == 1 ? "1 session" : absl::StrCat(still, " sessions"),
                   still == 1 ? "s" : "", still == 1 ? "it ends" : "they end");
    }
  }
  if (inv.global.json) PrintJson(out);
  return rc;
}

}  // namespace

const Command kInfoCommand = {"info", "what the server is, what it can do and how busy it is",
                              R"(usage: tessera info
Prints the server's version, device, driver, limits, setting choices and defaults, uptime,
scenes, sessions and queue depth (GetServerInfo). --json: the whole ServerInfo (plus
"server": the address asked).
)",
                              false, RunInfo};

const Command kScenesCommand = {"scenes", "list the scenes on the server",
                                R"(usage: tessera scenes
Lists the scenes on the server: id (first 12 characters; a unique prefix of 8+ works where a
scene id is wanted), name, triangles, device memory, streaming sessions using it, and whether it is
deleted but still in use. --json: {"scenes": [SceneInfo, ...]}, every field.
)",
                                false, RunScenes};

const Command kRmCommand = {"rm", "delete scenes from the server",
                            R"(usage: tessera rm ID...
Deletes scenes (DeleteScene). ID is a full scene id or a unique prefix of 8+ characters.
Sessions still rendering a scene keep it until they end; the output says how many there are.
Every ID is tried; the exit status is 1 if any of them failed.
--json: an array with one object per ID: {"scene_id", "sessions_still_using"}, or
{"scene_id": ID as given, "error": {"code", "message"}}.
)",
                            false, RunRm};

}  // namespace tessera::cli
