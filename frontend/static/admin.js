// Accounts: one's own password and logins; for an admin, every account (create,
// role, disable or enable, new password).
import * as api from "/static/api_client.js";
import { $, act, fmtDate, formData, h, showFatal } from "/static/dom.js";

function deviceCell(u, granted, me) {
  if (u.role === "admin") return h("td", {}, "yes (admin)");
  const has = granted.has(u.username);
  return h("td", {}, has ? "yes " : "no ", h("button", {
    type: "button",
    class: "toggle-device",
    onclick: (ev) => act(ev.target, $("#users-msg"), async () => {
      if (has) await api.accounts.revokeDevice(u.username);
      else await api.accounts.grantDevice(u.username);
      await loadUsers(me);
      return `${u.username}: device grant ${has ? "revoked" : "given"}`;
    }),
  }, has ? "Revoke" : "Grant"));
}

async function loadUsers(me) {
  const [users, grants] = await Promise.all([api.accounts.listUsers(),
    api.accounts.listDeviceGrants()]);
  const granted = new Set(grants.map((g) => g.username));
  $("#users tbody").replaceChildren(...users.map((u) => h("tr", { "data-user": u.username },
    h("td", {}, u.username),
    h("td", {}, u.role),
    h("td", {}, u.active ? "active" : "disabled"),
    deviceCell(u, granted, me),
    h("td", {}, fmtDate(u.created_at)),
    h("td", {}, u.id === me.id ? "(you)" : h("button", {
      type: "button",
      class: "toggle-active",
      onclick: (ev) => act(ev.target, $("#users-msg"), async () => {
        await api.accounts.updateUser(u.id, { active: !u.active });
        await loadUsers(me);
        return `${u.username} ${u.active ? "disabled" : "enabled"}`;
      }),
    }, u.active ? "Disable" : "Enable")))));
}

async function main() {
  const me = await api.auth.me();
  if (me.role === "admin") {
    $("#admin-only").hidden = false;
    await loadUsers(me);
    $("#user-form").addEventListener("submit", (ev) => {
      ev.preventDefault();
      act($("#user-create"), $("#user-msg"), async () => {
        const u = await api.accounts.addUser(formData(ev.target));
        ev.target.reset();
        await loadUsers(me);
        return `created ${u.username}`;
      });
    });
  } else {
    $("#not-admin").hidden = false;
  }
  const members = api.studies.setMember;
  $("#members-route").textContent = `${members.method} ${members.path}`;
  document.body.dataset.ready = "true";
}

$("#password-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  act($("#password-change"), $("#password-msg"), async () => {
    await api.auth.changePassword(formData(ev.target));
    ev.target.reset();
    return "password changed; your other logins ended";
  });
});

$("#revoke-all").addEventListener("click", async () => {
  await api.auth.revokeAll();
  location.assign("/login");
});

main().catch(showFatal);
