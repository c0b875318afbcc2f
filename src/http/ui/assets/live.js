// accelcal's pages, kept current from the event stream (issue 47 item 5).
//
// A page that shows what events change (the fleet, a sensor) names its
// stream in <main data-live="/ui/events?...">. On every event the page
// fetches itself again and swaps its <main> for the new one: no timer, no
// polling, and nothing changes while nothing happens. Events that arrive
// while a refresh is under way make one more refresh after it, and
// refreshes are at least a second apart, so a busy laboratory's stream
// costs the server one page per second per open page at most. A form
// control the reader is using is never swapped away: the refresh waits
// until it loses focus. Without JavaScript (or EventSource) the page is
// the same page, refreshed by hand.
(() => {
  "use strict";
  const main = document.querySelector("main[data-live]");
  const status = document.getElementById("live-status");
  if (!main || !status || !("EventSource" in window)) return;
  const GAP_MS = 1000;
  let last = 0;
  let busy = false;
  let again = false;
  let why = "";

  const typing = () => {
    const a = document.activeElement;
    return a && a !== document.body && document.querySelector("main").contains(a)
      && /^(INPUT|SELECT|TEXTAREA)$/.test(a.tagName);
  };

  const refresh = async () => {
    if (busy) { again = true; return; }
    if (typing()) {
      document.activeElement.addEventListener("blur", () => refresh(), { once: true });
      return;
    }
    const wait = last + GAP_MS - Date.now();
    if (wait > 0) { busy = true; setTimeout(() => { busy = false; refresh(); }, wait); return; }
    busy = true;
    last = Date.now();
    try {
      const res = await fetch(location.href, { credentials: "same-origin", headers: { accept: "text/html" } });
      if (!res.ok) throw new Error(`the page answered ${res.status}`);
      const page = new DOMParser().parseFromString(await res.text(), "text/html");
      const fresh = page.querySelector("main[data-live]");
      if (!fresh) throw new Error("the page came back without its content");
      document.querySelector("main").replaceWith(document.adoptNode(fresh));
      document.title = page.title;
      status.dataset.refreshes = String(Number(status.dataset.refreshes || 0) + 1);
      status.textContent = `Updated ${new Date().toLocaleTimeString()} (${why}).`;
    } catch (e) {
      status.textContent = `Could not update (${e.message}); reload the page to see the latest.`;
    } finally {
      busy = false;
      if (again) { again = false; refresh(); }
    }
  };

  const source = new EventSource(main.dataset.live);
  source.onopen = () => { status.dataset.state = "open"; };
  source.onmessage = (m) => {
    status.dataset.events = String(Number(status.dataset.events || 0) + 1);
    try { why = JSON.parse(m.data).type; } catch { why = "an event"; }
    refresh();
  };
  // The browser reconnects by itself after a lost connection; a stream
  // refused (the session ended: the server answers 204) is closed for good,
  // and reloading shows the latest or, the session gone, the sign-in form.
  source.onerror = () => {
    if (source.readyState === EventSource.CLOSED) {
      status.dataset.state = "closed";
      status.textContent = "Live updates stopped; reload the page to see the latest.";
    } else {
      status.dataset.state = "reconnecting";
    }
  };
})();
