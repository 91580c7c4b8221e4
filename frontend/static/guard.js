// Loaded first by every experimenter page (a classic script, before the modules).
// 1. While an account still has the published demo password, every page says so.
// 2. The header names who is logged in (the page shell leaves it a place, #who).
// (The CSRF header every change carries is set by the one request function, api.js.)
(() => {
  async function warn() {
    // A classic script cannot import statically; the client is a module like the pages.
    const [{ auth }, { respond }] = await Promise.all([
      import("/static/api_client.js"), import("/static/api.js")]);
    const r = await respond("GET", auth.me.url());
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
