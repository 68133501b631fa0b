// The instructor's panel beside the scene: the overlay's lines (scene, each participant's id, role, mode, round
// trip, force against the device's limit, skill state; the exercise's live score) and a plot of each tool's
// force over the last seconds, with each device's limit dashed.

const PLOT_SECONDS = 10;
const TOOL_COLOURS = ['#4fc3f7', '#ffb74d', '#81c784', '#e57373', '#ba68c8', '#fff176'];

function css(rgb) {
  const c = rgb.map((v) => Math.round(255 * Math.max(0, Math.min(1, v))));
  return `rgb(${c[0]},${c[1]},${c[2]})`;
}

export class Panel {
  constructor(overlay, plot) {
    this.overlay = overlay;
    this.plot = plot;
    this.history = new Map(); // tool -> [{t, f}]
    this.limits = new Map(); // tool -> N
    this.names = new Map(); // tool -> device id
  }

  setState(state) {
    this.overlay.replaceChildren(...state.lines.map((line) => {
      const div = document.createElement('div');
      div.textContent = line.text;
      div.style.color = css(line.rgb);
      return div;
    }));
    const t = state.simTimeS;
    for (const tool of state.tools) {
      let h = this.history.get(tool.tool);
      if (!h) { h = []; this.history.set(tool.tool, h); }
      // A restarted server counts time from zero again: start the trace afresh.
      if (h.length && t < h[h.length - 1].t) h.length = 0;
      h.push({ t, f: tool.forceN });
      while (h.length && h[0].t < t - PLOT_SECONDS) h.shift();
      this.limits.set(tool.tool, tool.limitN);
      this.names.set(tool.tool, tool.deviceId);
    }
    this.draw(t);
  }

  draw(now) {
    // Draw at the canvas's size on the page, in device pixels, so text stays sharp at any width.
    const ratio = window.devicePixelRatio || 1;
    const w = this.plot.clientWidth || 360, h = this.plot.clientHeight || 180;
    if (this.plot.width !== Math.round(w * ratio) || this.plot.height !== Math.round(h * ratio)) {
      this.plot.width = Math.round(w * ratio);
      this.plot.height = Math.round(h * ratio);
    }
    const c = this.plot.getContext('2d');
    c.setTransform(ratio, 0, 0, ratio, 0, 0);
    c.clearRect(0, 0, w, h);
    const limits = [...this.limits.values()].filter((l) => l > 0);
    let top = Math.max(1, ...limits);
    for (const h2 of this.history.values()) for (const p of h2) top = Math.max(top, p.f);
    top *= 1.1;
    const x = (t) => w * (1 - (now - t) / PLOT_SECONDS);
    const y = (f) => h - 16 - (h - 24) * (f / top);
    c.font = '11px system-ui, sans-serif';
    c.fillStyle = '#8a93a3';
    c.fillText(`${top.toFixed(1)} N`, 4, 12);
    c.fillText(`-${PLOT_SECONDS} s`, 4, h - 3);
    c.fillText('now', w - 24, h - 3);
    let k = 0;
    for (const [tool, points] of this.history) {
      const colour = TOOL_COLOURS[k++ % TOOL_COLOURS.length];
      const limit = this.limits.get(tool);
      if (limit > 0) {
        c.setLineDash([4, 4]); c.strokeStyle = colour; c.globalAlpha = 0.5;
        c.beginPath(); c.moveTo(0, y(limit)); c.lineTo(w, y(limit)); c.stroke();
        c.setLineDash([]); c.globalAlpha = 1;
      }
      c.strokeStyle = colour; c.lineWidth = 2;
      c.beginPath();
      points.forEach((p, i) => (i ? c.lineTo(x(p.t), y(p.f)) : c.moveTo(x(p.t), y(p.f))));
      c.stroke();
      c.fillStyle = colour;
      c.fillText(this.names.get(tool) ?? `tool ${tool}`, w - 70, 12 + 13 * (k - 1));
    }
  }
}
