// The workshop page's drawings: the piece as far as it is wound, and the guide's reference.
"use strict";

// A plan's piece on a canvas, drawn step by step: each new executed step adds its chord, so an
// update costs only the chords wound since the last one.
class Piece {
  constructor(canvas, overlay) {
    this.canvas = canvas;
    this.overlay = overlay;
    this.plan = null;
    this.drawn = 0;
    this.layerOf = [];
    this.steps = [];
  }

  setPlan(drawing) {
    this.plan = drawing;
    this.steps = [];
    this.layerOf = [];
    drawing.layers.forEach((layer, k) => {
      layer.sequence.forEach((pin, i) => {
        this.steps.push(pin);
        this.layerOf.push(i === 0 ? -1 - k : k); // a layer's first pin starts a new thread: no chord
      });
    });
    this.clear();
  }

  size() { return this.canvas.width; }

  xy(pin) {
    const s = this.size(), m = 6, p = this.plan.pin_xy[pin];
    return [m + p[0] * (s - 2 * m), m + p[1] * (s - 2 * m)];
  }

  clear() {
    const ctx = this.canvas.getContext("2d");
    ctx.globalAlpha = 1;
    ctx.fillStyle = "#f3f1ec";
    ctx.fillRect(0, 0, this.size(), this.size());
    if (this.plan) {
      ctx.fillStyle = this.plan.background;
      ctx.beginPath();
      const s = this.size();
      if (this.plan.pin_xy.length && this.isCircle()) {
        ctx.arc(s / 2, s / 2, s / 2 - 6, 0, 2 * Math.PI);
      } else {
        ctx.rect(6, 6, s - 12, s - 12);
      }
      ctx.fill();
    }
    this.drawn = 0;
  }

  isCircle() {
    const p = this.plan.pin_xy[0];
    return Math.abs(p[0] - 0.5) < 1e-3 && p[1] < 0.01;
  }

  // Draw the chords of steps [drawn, done): steps are counted over every layer, as the journal does.
  upTo(done) {
    if (!this.plan) return;
    done = Math.max(0, Math.min(done, this.steps.length));
    if (done < this.drawn) this.clear();
    const ctx = this.canvas.getContext("2d");
    const px = this.plan.thread_fraction * (this.size() - 12);
    ctx.lineWidth = Math.max(px, 0.6);
    ctx.globalAlpha = Math.min(1, Math.max(0.12, px / ctx.lineWidth));
    ctx.lineCap = "round";
    for (let i = Math.max(this.drawn, 1); i < done; i++) {
      const k = this.layerOf[i];
      if (k < 0) continue;
      ctx.strokeStyle = this.plan.layers[k].color;
      ctx.beginPath();
      ctx.moveTo(...this.xy(this.steps[i - 1]));
      ctx.lineTo(...this.xy(this.steps[i]));
      ctx.stroke();
    }
    this.drawn = Math.max(this.drawn, done);
    this.mark(done);
  }

  // The overlay: the pins faintly, the last pin hooked and the next one.
  mark(done) {
    const ctx = this.overlay.getContext("2d");
    ctx.clearRect(0, 0, this.size(), this.size());
    if (!this.plan) return;
    ctx.fillStyle = "rgba(60,60,60,0.35)";
    for (let pin = 0; pin < this.plan.pin_xy.length; pin++) {
      const [x, y] = this.xy(pin);
      ctx.fillRect(x - 0.6, y - 0.6, 1.2, 1.2);
    }
    const dot = (pin, color, r) => {
      const [x, y] = this.xy(pin);
      ctx.beginPath();
      ctx.arc(x, y, r, 0, 2 * Math.PI);
      ctx.fillStyle = color;
      ctx.fill();
    };
    if (done > 0) dot(this.steps[done - 1], "#d1495b", 4.5);
    if (done < this.steps.length) {
      ctx.strokeStyle = "#2a6f97";
      ctx.lineWidth = 1.5;
      const [x, y] = this.xy(this.steps[done]);
      ctx.beginPath();
      ctx.arc(x, y, 6, 0, 2 * Math.PI);
      ctx.stroke();
    }
  }
}

// The guide's reference as an SVG: the ring turned so that pin `pin` faces the head station
// (at the top), the head IN, the gaps either side of it marked.
function referenceSvg(pins, pin, gap) {
  const s = 260, c = s / 2, r = 100, ns = "http://www.w3.org/2000/svg";
  const svg = document.createElementNS(ns, "svg");
  svg.setAttribute("viewBox", `0 0 ${s} ${s + 22}`);
  svg.setAttribute("class", "reference");
  const el = (name, attrs, text) => {
    const e = document.createElementNS(ns, name);
    for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
    if (text !== undefined) e.textContent = text;
    svg.appendChild(e);
    return e;
  };
  el("circle", {cx: c, cy: c + 8, r: r + 14, fill: "#f6f4ef", stroke: "#c9c2b5"});
  const at = (p, rr) => {       // pin p, with pin `pin` at the top (the station), clockwise
    const a = ((p - pin) / pins) * 2 * Math.PI;
    return [c + rr * Math.sin(a), c + 8 - rr * Math.cos(a)];
  };
  for (let p = 0; p < pins; p++) {
    const [x, y] = at(p, r);
    el("circle", {cx: x, cy: y, r: p === pin ? 4 : 1.3, fill: p === pin ? "#d1495b" : "#6b6459"});
  }
  for (let p = 0; p < pins; p += Math.max(1, Math.round(pins / 12))) {
    const [x, y] = at(p, r - 16);
    el("text", {x, y: y + 3, "text-anchor": "middle", class: "tick"}, String(p));
  }
  // the head station at the top: the head IN, its eyelet inside the pin circle
  el("rect", {x: c - 7, y: 0, width: 14, height: 22, rx: 3, fill: "#2a6f97"});
  el("line", {x1: c, y1: 22, x2: c, y2: 8 + c - r + 16, stroke: "#2a6f97", "stroke-width": 3});
  el("circle", {cx: c, cy: 8 + c - r + 16, r: 3.5, fill: "#fff", stroke: "#2a6f97", "stroke-width": 2});
  const [px, py] = at(pin, r);
  el("text", {x: px + 10, y: py + 16, class: "label"}, `pin ${pin}`);
  if (gap !== null && gap !== undefined) {
    const [gx, gy] = at(gap + 0.5, r);
    el("circle", {cx: gx, cy: gy, r: 6, fill: "none", stroke: "#e09f3e", "stroke-width": 2});
  }
  el("text", {x: c, y: s + 18, "text-anchor": "middle", class: "caption"},
     `the reference: pin ${pin} at the head, the head IN`);
  return svg;
}

window.Piece = Piece;
window.referenceSvg = referenceSvg;
