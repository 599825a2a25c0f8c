// The users allowed to call methods: one line per user, "name:scrypt:SALT_HEX:HASH_HEX",
// scrypt N=16384 r=8 p=1, 32-byte key (Python: hashlib.scrypt(pw, salt=salt, n=16384, r=8,
// p=1, dklen=32)). Lines starting with # and blank lines are ignored. No plain passwords
// on disk, comparison in constant time (IEC 62443-4-2 CR 1.5, authenticator management).
import * as crypto from "crypto";
import * as fs from "fs";

const SCRYPT = { N: 16384, r: 8, p: 1 };
const KEY_LEN = 32;

interface Entry {
  salt: Buffer;
  hash: Buffer;
}

export class Users {
  private readonly entries = new Map<string, Entry>();

  static load(file: string): Users {
    const users = new Users();
    const lines = fs.readFileSync(file, "utf8").split(/\r?\n/);
    lines.forEach((line, i) => {
      if (line.trim() === "" || line.startsWith("#")) {
        return;
      }
      const m = /^([A-Za-z0-9_.@-]{1,64}):scrypt:([0-9a-f]{16,128}):([0-9a-f]{64})$/.exec(line);
      if (m === null) {
        throw new Error(`${file}:${i + 1}: expected name:scrypt:SALT_HEX:HASH_HEX (see --hash-password)`);
      }
      users.entries.set(m[1], { salt: Buffer.from(m[2], "hex"), hash: Buffer.from(m[3], "hex") });
    });
    if (users.entries.size === 0) {
      throw new Error(`${file}: no user`);
    }
    return users;
  }

  get size(): number {
    return this.entries.size;
  }

  check(name: string, password: string): boolean {
    const e = this.entries.get(name);
    // Hash even for an unknown name, so the time taken does not tell which names exist.
    const salt = e?.salt ?? Buffer.alloc(16);
    const got = crypto.scryptSync(password, salt, KEY_LEN, SCRYPT);
    return e !== undefined && crypto.timingSafeEqual(got, e.hash);
  }
}

export function hashLine(name: string, password: string): string {
  const salt = crypto.randomBytes(16);
  const hash = crypto.scryptSync(password, salt, KEY_LEN, SCRYPT);
  return `${name}:scrypt:${salt.toString("hex")}:${hash.toString("hex")}`;
}
