// Latest-wins delivery of frames to one WebSocket, as tesserad's own sessions do it: at most
// one frame is in the socket at a time per stream; a frame that arrives while one is in
// flight waits in a single slot, and a newer one replaces it. A slow browser gets fewer
// frames, never a backlog and never an old frame after a newer one.
export class LatestSender {
  /**
   * @param send (data, done) => void: writes `data` and calls done(err) once it is handed to
   *        the socket (ws's send callback).
   */
  constructor(send) {
    this.send_ = send;
    this.inFlight_ = false;
    this.waiting_ = null;
    this.closed_ = false;
    this.sent = 0;
    this.dropped = 0;
  }

  /** Queues `data` (the newest frame), replacing a frame still waiting. */
  push(data) {
    if (this.closed_) return;
    if (this.inFlight_) {
      if (this.waiting_ !== null) this.dropped++;
      this.waiting_ = data;
      return;
    }
    this.write_(data);
  }

  /** Drops what waits; later pushes are ignored. */
  close() {
    this.closed_ = true;
    this.waiting_ = null;
  }

  write_(data) {
    this.inFlight_ = true;
    this.sent++;
    this.send_(data, (err) => {
      this.inFlight_ = false;
      if (err || this.closed_) {
        this.waiting_ = null;
        return;
      }
      const next = this.waiting_;
      this.waiting_ = null;
      if (next !== null) this.write_(next);
    });
  }
}
