// Log in with the JSON endpoint (it sets the httponly session cookie), then go back to
// the page that sent us here. Only same-site paths are followed, never another origin.
import { respond } from "/static/api.js";
import * as api from "/static/api_client.js";

const form = document.getElementById("login");
const error = document.getElementById("login-error");

function nextPath() {
  // Only a path on this site: browsers read "/\evil.example" as "//evil.example", so
  // resolve the value the way the browser will and compare origins.
  const next = new URLSearchParams(location.search).get("next") || "/live";
  if (!next.startsWith("/") || /[\\\s]/.test(next)) return "/live";
  let url;
  try {
    url = new URL(next, location.origin);
  } catch {
    return "/live";
  }
  return url.origin === location.origin ? url.pathname + url.search + url.hash : "/live";
}

form.addEventListener("submit", async (event) => {
  event.preventDefault();
  error.textContent = "";
  const body = {
    username: document.getElementById("username").value,
    password: document.getElementById("password").value,
  };
  // Not through api.auth.login(): a refused login must stay here, not go to the login page.
  const r = await respond("POST", api.auth.login.url(), body);
  if (r.ok) {
    location.assign(nextPath());
  } else {
    const detail = (await r.json().catch(() => ({}))).detail;
    error.textContent = typeof detail === "string" ? detail : "login failed";
  }
});
