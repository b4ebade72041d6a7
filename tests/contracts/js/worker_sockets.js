// skinsynth view's page in a test or benchmark: runs before the page's scripts. viser's client keeps its
// websocket in a Web Worker; every worker starts by wrapping WebSocket, keeping its sockets in
// self.__sockets (so the page can send what a gizmo sends) and calling self.__onFrame(bytes), when set,
// for each frame it receives (before the client's own handler, which hands the buffer over).
(() => {
  const NativeWorker = window.Worker;
  const prelude = `(() => { const N = self.WebSocket; self.__sockets = [];
    const W = function (...a) {
      const s = new N(...a); self.__sockets.push(s);
      // first in line (the client's own handler hands the buffer over to the page, emptying it)
      s.addEventListener("message", (e) => { if (self.__onFrame) self.__onFrame(
        e.data.byteLength !== undefined ? e.data.byteLength : e.data.size); });
      return s; };
    W.prototype = N.prototype; Object.assign(W, {CONNECTING: 0, OPEN: 1, CLOSING: 2, CLOSED: 3});
    self.WebSocket = W; })();\n`;
  window.Worker = function (url, options) {
    const module = options && options.type === "module";
    const body = prelude + (module ? `import ${JSON.stringify(String(url))};`
                                   : `importScripts(${JSON.stringify(String(url))});`);
    return new NativeWorker(URL.createObjectURL(new Blob([body], {type: "text/javascript"})), options);
  };
  window.Worker.prototype = NativeWorker.prototype;
})();
