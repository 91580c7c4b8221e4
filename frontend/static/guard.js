// Loaded first by every experimenter page (a classic script, before the modules).
// 1. Every same-origin change (POST, PUT, PATCH, DELETE) carries the CSRF token the
//    server set at login, as the X-CSRF-Token header: the server refuses a change made
//    with the session cookie without it, so another site cannot act with the cookie.
// 2. While an account still has the published demo password, every page says so.
// 3. The header names who is logged in (the page shell leaves it a place, #who).
(() => {
  const SAFE = new Set(["GET", "HEAD", "OPTIONS"]);
  const token = () => {
    const m = document.cookie.match(/(?:^|; )exostudy_csrf=([^;]+)/);
    return m ? decodeURIComponent(m[1]) : "";
  };
  const original = window.fetch.bind(window);
  window.fetch = (input, init = {}) => {
    const isRequest = input instanceof Request;
    const method = (init.method || (isRequest ? input.method : "GET")).toUpperCase();
    const url = new URL(isRequest ? input.url : String(input), location.href);
    if (!SAFE.has(method) && url.origin === location.origin) {
      const headers = new Headers(init.headers || (isRequest ? input.headers : undefined));
      headers.set("X-CSRF-Token", token());
      init = { ...init, headers };
    }
    return original(input, init);
  };

  async function warn() {
    // A classic script cannot import statically; the client is a module like the pages.
    const { auth } = await import("/static/api_client.js");
    const r = await original(auth.me.url());
    if (!r.ok) return;
    const me = await r.json();
    const who = document.getElementById("who");
    if (who) who.textContent = `${me.username} (${me.role})`;
    const names = me.published_login_accounts || [];
    if (!names.length) return;
    const banner = document.createElement("div");
    banner.id = "published-password-warning";
    banner.className = "security-warning";
    banner.setAttribute("role", "alert");
    banner.textContent = `Account ${names.join(", ")} still has the published demo ` +
      "password: anyone who reads the README can log in. Change it (Accounts page or " +
      "`exostudy user passwd NAME`) before this server is reachable from the network.";
    document.body.prepend(banner);
  }
  if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", warn);
  else warn();
})();
