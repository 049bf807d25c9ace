// A static HTTP/1.0 server for the viewer: GET and HEAD of a fixed set of files, one thread per
// connection (a browser opens idle connections ahead of time; one thread must not wait on them).
#include "view_command.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "run.h"

#ifndef DRAPE_VIEWER_DIR
#define DRAPE_VIEWER_DIR ""
#endif

namespace drape::app {

namespace fs = std::filesystem;

namespace {

void send_all(int fd, const char* data, std::size_t size) {
  while (size > 0) {
    const ssize_t n = ::send(fd, data, size, MSG_NOSIGNAL);
    if (n <= 0) return;
    data += n;
    size -= std::size_t(n);
  }
}

void respond(int fd, const std::map<std::string, fs::path>& files) {
  timeval timeout{10, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  std::string request;
  char buf[2048];
  while (request.find("\r\n\r\n") == std::string::npos && request.size() < 16384) {
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    request.append(buf, std::size_t(n));
  }
  std::istringstream line(request.substr(0, request.find("\r\n")));
  std::string method, target;
  line >> method >> target;
  target = target.substr(0, target.find('?'));
  auto reply = [&](const std::string& status, const std::string& type, const std::string& body, bool head) {
    const std::string header = "HTTP/1.0 " + status + "\r\nContent-Type: " + type +
                               "\r\nContent-Length: " + std::to_string(body.size()) +
                               "\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n";
    send_all(fd, header.data(), header.size());
    if (!head) send_all(fd, body.data(), body.size());
  };
  if (method != "GET" && method != "HEAD") {
    reply("405 Method Not Allowed", "text/plain", "only GET\n", false);
  } else if (const auto it = files.find(target == "/" ? "/index.html" : target); it == files.end()) {
    reply("404 Not Found", "text/plain", "not found\n", method == "HEAD");
  } else {
    std::ifstream in(it->second, std::ios::binary);
    std::stringstream body;
    body << in.rdbuf();
    const std::string ext = it->second.extension().string();
    const std::string type = ext == ".html" ? "text/html; charset=utf-8"
                             : ext == ".js" ? "text/javascript"
                             : ext == ".glb" ? "model/gltf-binary"
                                             : "application/octet-stream";
    if (!in && !in.eof())
      reply("500 Internal Server Error", "text/plain", "cannot read " + it->first + "\n", method == "HEAD");
    else
      reply("200 OK", type, body.str(), method == "HEAD");
  }
  ::close(fd);
}

}  // namespace

CLI::App* add_view_subcommand(CLI::App& app, ViewArgs& args) {
  CLI::App* view = app.add_subcommand(
      "view", "Serve the browser viewer of a run on localhost: play OUT_DIR/run.glb (drape run --format glb)");
  view->add_option("OUT_DIR", args.out_dir, "Output folder of `drape run` holding run.glb")->required();
  view->add_option("--port", args.port, "TCP port on 127.0.0.1 (default 8018; 0: any free port)")
      ->check(CLI::Range(0, 65535));
  view->add_option("--viewer-dir", args.viewer_dir,
                   "The built viewer (index.html, viewer.js); default: the build's apps/viewer/dist");
  return view;
}

int view_command(const ViewArgs& args, std::ostream& log) {
  const fs::path glb = fs::path(args.out_dir) / glb_file_name;
  std::error_code ec;
  if (!fs::is_regular_file(glb, ec)) {
    log << "drape: view " << args.out_dir << ": no " << glb_file_name << " there; write one with `drape run SCENE --out "
        << args.out_dir << " --format glb`\n";
    return exit_usage;
  }
  const fs::path viewer = args.viewer_dir.empty() ? fs::path(DRAPE_VIEWER_DIR) : fs::path(args.viewer_dir);
  std::map<std::string, fs::path> files{{"/run.glb", glb}};
  for (const char* name : {"index.html", "viewer.js"}) {
    if (!fs::is_regular_file(viewer / name, ec)) {
      log << "drape: view: the viewer is not built: " << (viewer / name).string()
          << " is missing (it is built with the program when npm is installed: see apps/viewer/README.md)\n";
      return exit_usage;
    }
    files["/" + std::string(name)] = viewer / name;
  }

  const int server = ::socket(AF_INET, SOCK_STREAM, 0);
  const int yes = 1;
  ::setsockopt(server, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);  // never reachable from other machines
  address.sin_port = htons(static_cast<std::uint16_t>(args.port));
  if (server < 0 || ::bind(server, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 ||
      ::listen(server, 16) != 0) {
    log << "drape: view: cannot listen on 127.0.0.1:" << args.port << ": " << std::strerror(errno)
        << (errno == EADDRINUSE ? " (choose another --port, or 0 for any free one)" : "") << '\n';
    return exit_write_failed;
  }
  socklen_t length = sizeof address;
  ::getsockname(server, reinterpret_cast<sockaddr*>(&address), &length);
  log << "drape: serving " << glb.string() << " at http://127.0.0.1:" << ntohs(address.sin_port)
      << "/ (Ctrl-C stops)" << std::endl;
  while (true) {
    const int client = ::accept(server, nullptr, nullptr);
    if (client < 0) {
      if (errno == EINTR) continue;
      log << "drape: view: accept failed: " << std::strerror(errno) << '\n';
      return exit_write_failed;
    }
    std::thread(respond, client, files).detach();
  }
}

}  // namespace drape::app
