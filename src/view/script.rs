//! `cssm view --script FILE`: input read from a file, one step a line, each step turned into
//! the input events a person makes (a press, a cursor motion, a release; a key press and
//! release) and fed to the window's own event handling, one step per frame. The format is in
//! `cssm view --help`:
//!
//! ```text
//! # comment
//! orbit DX DY          left drag by DX, DY pixels
//! drag-light DX DY     right drag (aim the first spot light)
//! move-light DX DY     shift + right drag (move it in the view plane)
//! dolly LINES          the wheel, LINES lines
//! key KEY              press and release KEY (c, [, Tab, F12, shift+Tab, ...)
//! hold KEY N           press KEY, let N frames render, release it (a held fly key)
//! wait N               let N frames render
//! animate SECONDS      move the objects' animation SECONDS on (as P plays it, but exactly)
//! screenshot PATH      write the last frame (PNG, or .exr: linear radiance)
//! quit                 close the window
//! ```

use std::path::{Path, PathBuf};

use winit::{
    event::MouseButton,
    keyboard::{Key, KeyCode, NamedKey, PhysicalKey},
};

/// Most frames one `wait` takes (as `--frames`).
const MAX_WAIT: u32 = 4096;

/// A key of a `key` step: what a keyboard sends for it.
#[derive(Clone, Debug, PartialEq)]
pub struct ScriptKey {
    /// Its place on the keyboard (US layout).
    pub physical: PhysicalKey,
    /// What it types, shift applied.
    pub logical: Key,
    /// Shift held.
    pub shift: bool,
}

/// One step of a script.
#[derive(Clone, Debug, PartialEq)]
pub enum Step {
    /// A drag of `dx`, `dy` pixels with `button` held (and shift, for `move-light`).
    Drag {
        /// The button held.
        button: MouseButton,
        /// Shift held.
        shift: bool,
        /// Pixels right.
        dx: f64,
        /// Pixels down.
        dy: f64,
    },
    /// The wheel turned this many lines.
    Dolly(f32),
    /// A key pressed and released.
    Key(ScriptKey),
    /// A key pressed, held for this many frames, and released.
    Hold(ScriptKey, u32),
    /// This many frames before the next step.
    Wait(u32),
    /// The objects' animation moved this many seconds on (back, when negative).
    Animate(f32),
    /// The last frame written here.
    Screenshot(PathBuf),
    /// The window closed.
    Quit,
}

/// A step and the line it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct Line {
    /// 1-based line number.
    pub number: usize,
    /// The step.
    pub step: Step,
}

/// The longest script read: a tour of thousands of steps is a few hundred kilobytes.
pub const MAX_SCRIPT_BYTES: u64 = 1 << 20;

/// Reads and parses the script at `path`; errors name the file and line.
pub fn load(path: &Path) -> Result<Vec<Line>, String> {
    let cannot =
        |e: &dyn std::fmt::Display| format!("cannot read the script {}: {e}", path.display());
    // Opened as every input is (a FIFO would block the open for ever, a device never end).
    let bytes =
        cssm_formats::files::read_bounded(path, MAX_SCRIPT_BYTES).map_err(|e| cannot(&e))?;
    let text = String::from_utf8(bytes).map_err(|_| cannot(&"it is not UTF-8 text"))?;
    parse(&text).map_err(|(line, problem)| format!("{}:{line}: {problem}", path.display()))
}

/// Parses a script's text; an error is its line number and the problem.
pub fn parse(text: &str) -> Result<Vec<Line>, (usize, String)> {
    let mut steps = Vec::new();
    for (index, raw) in text.lines().enumerate() {
        let number = index + 1;
        let content = raw.split('#').next().unwrap_or("").trim();
        if content.is_empty() {
            continue;
        }
        let step = parse_step(content).map_err(|problem| (number, problem))?;
        steps.push(Line { number, step });
    }
    Ok(steps)
}

fn parse_step(line: &str) -> Result<Step, String> {
    let mut words = line.split_whitespace();
    let command = words.next().unwrap_or_default();
    let args: Vec<&str> = words.collect();
    let count = |n: usize| -> Result<(), String> {
        if args.len() == n {
            Ok(())
        } else {
            Err(format!(
                "'{command}' takes {n} argument{}, not {}: {line}",
                if n == 1 { "" } else { "s" },
                args.len()
            ))
        }
    };
    let number = |text: &str| -> Result<f64, String> {
        match text.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(format!("'{text}' is not a finite number: {line}")),
        }
    };
    let drag = |button, shift| -> Result<Step, String> {
        count(2)?;
        Ok(Step::Drag {
            button,
            shift,
            dx: number(args[0])?,
            dy: number(args[1])?,
        })
    };
    match command {
        "orbit" => drag(MouseButton::Left, false),
        "drag-light" => drag(MouseButton::Right, false),
        "move-light" => drag(MouseButton::Right, true),
        "dolly" => {
            count(1)?;
            Ok(Step::Dolly(number(args[0])? as f32))
        }
        "key" => {
            count(1)?;
            parse_key(args[0]).map(Step::Key)
        }
        "hold" => {
            count(2)?;
            Ok(Step::Hold(parse_key(args[0])?, frames(command, args[1])?))
        }
        "wait" => {
            count(1)?;
            Ok(Step::Wait(frames(command, args[0])?))
        }
        "animate" => {
            count(1)?;
            Ok(Step::Animate(number(args[0])? as f32))
        }
        "screenshot" => {
            // The rest of the line: a path may hold spaces.
            let path = line["screenshot".len()..].trim();
            if path.is_empty() {
                return Err("screenshot takes a path: screenshot PATH".into());
            }
            Ok(Step::Screenshot(PathBuf::from(path)))
        }
        "quit" => {
            count(0)?;
            Ok(Step::Quit)
        }
        other => Err(format!(
            "unknown step '{other}' (the steps: orbit, drag-light, move-light, dolly, key, \
             hold, wait, animate, screenshot, quit; `cssm view --help` describes them)"
        )),
    }
}

/// A frame count of `wait` or `hold`: 1 to [`MAX_WAIT`].
fn frames(command: &str, text: &str) -> Result<u32, String> {
    match text.parse::<u32>() {
        Ok(n) if (1..=MAX_WAIT).contains(&n) => Ok(n),
        _ => Err(format!(
            "{command} takes a whole number of frames from 1 to {MAX_WAIT}, not '{text}'"
        )),
    }
}

/// `KEY` or `shift+KEY`: a named key (Tab, F12, Escape) or one character of the US layout.
fn parse_key(text: &str) -> Result<ScriptKey, String> {
    let (shift, name) = match text.split_once('+') {
        Some((modifier, name)) if modifier.eq_ignore_ascii_case("shift") && !name.is_empty() => {
            (true, name)
        }
        _ => (false, text),
    };
    let named = |code, key| (PhysicalKey::Code(code), Key::Named(key));
    let (physical, logical) = match name.to_ascii_lowercase().as_str() {
        "tab" => named(KeyCode::Tab, NamedKey::Tab),
        "f12" => named(KeyCode::F12, NamedKey::F12),
        "escape" | "esc" => named(KeyCode::Escape, NamedKey::Escape),
        _ => {
            let mut chars = name.chars();
            let (Some(c), None) = (chars.next(), chars.next()) else {
                return Err(format!(
                    "unknown key '{name}': a character (c, [, ], -, =, h, w, ...), Tab, F12 \
                     or Escape, optionally shift+KEY"
                ));
            };
            let code = key_code(c.to_ascii_lowercase())
                .ok_or_else(|| format!("unknown key '{name}': not a key of the US layout"))?;
            // What the key types with shift held, as a keyboard reports it.
            let typed = match (shift, c) {
                (true, '=') => '+',
                (true, c) => c.to_ascii_uppercase(),
                (false, c) => c.to_ascii_lowercase(),
            };
            (
                PhysicalKey::Code(code),
                Key::Character(typed.to_string().into()),
            )
        }
    };
    Ok(ScriptKey {
        physical,
        logical,
        shift,
    })
}

/// The key of the US layout that types `c` (lower case).
fn key_code(c: char) -> Option<KeyCode> {
    use KeyCode::*;
    const LETTERS: [KeyCode; 26] = [
        KeyA, KeyB, KeyC, KeyD, KeyE, KeyF, KeyG, KeyH, KeyI, KeyJ, KeyK, KeyL, KeyM, KeyN, KeyO,
        KeyP, KeyQ, KeyR, KeyS, KeyT, KeyU, KeyV, KeyW, KeyX, KeyY, KeyZ,
    ];
    const DIGITS: [KeyCode; 10] = [
        Digit0, Digit1, Digit2, Digit3, Digit4, Digit5, Digit6, Digit7, Digit8, Digit9,
    ];
    Some(match c {
        'a'..='z' => LETTERS[(c as u8 - b'a') as usize],
        '0'..='9' => DIGITS[(c as u8 - b'0') as usize],
        '[' => BracketLeft,
        ']' => BracketRight,
        '-' => Minus,
        '=' => Equal,
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_script_parses_to_its_steps_with_line_numbers() {
        let text = "# a tour\norbit 40 -10\n\n  drag-light 5 0 # aim\nmove-light 1.5 2\n\
                    dolly -1\nkey shift+Tab\nkey =\nkey shift+=\nwait 3\nscreenshot a b.png\nquit\n\
                    hold w 5\nanimate -0.25\n";
        let lines = parse(text).unwrap();
        let numbers: Vec<usize> = lines.iter().map(|l| l.number).collect();
        assert_eq!(numbers, [2, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14]);
        assert_eq!(lines[11].step, Step::Animate(-0.25));
        assert_eq!(
            lines[0].step,
            Step::Drag {
                button: MouseButton::Left,
                shift: false,
                dx: 40.0,
                dy: -10.0
            }
        );
        assert!(matches!(
            lines[2].step,
            Step::Drag {
                button: MouseButton::Right,
                shift: true,
                ..
            }
        ));
        assert_eq!(lines[3].step, Step::Dolly(-1.0));
        let Step::Key(tab) = &lines[4].step else {
            panic!("{:?}", lines[4])
        };
        assert!(tab.shift && tab.logical == Key::Named(NamedKey::Tab));
        let Step::Key(plus) = &lines[6].step else {
            panic!("{:?}", lines[6])
        };
        assert_eq!(plus.logical, Key::Character("+".into()));
        assert_eq!(plus.physical, PhysicalKey::Code(KeyCode::Equal));
        assert_eq!(lines[7].step, Step::Wait(3));
        assert_eq!(lines[8].step, Step::Screenshot(PathBuf::from("a b.png")));
        assert_eq!(lines[9].step, Step::Quit);
        let Step::Hold(w, 5) = &lines[10].step else {
            panic!("{:?}", lines[10])
        };
        assert_eq!(w.physical, PhysicalKey::Code(KeyCode::KeyW));
    }

    #[test]
    fn bad_lines_name_their_number_and_problem() {
        for (text, line, problem) in [
            ("orbit 1\n", 1, "'orbit' takes 2 arguments, not 1"),
            ("wait 2\norbit 1 x\n", 2, "'x' is not a finite number"),
            ("\n\nwait 0\n", 3, "wait takes a whole number of frames"),
            ("key ctrl+c\n", 1, "unknown key 'ctrl+c'"),
            ("key ;\n", 1, "not a key of the US layout"),
            ("fly 1\n", 1, "unknown step 'fly'"),
            ("screenshot\n", 1, "screenshot takes a path"),
            ("quit now\n", 1, "'quit' takes 0 arguments"),
            ("hold w\n", 1, "'hold' takes 2 arguments"),
            ("hold w 0\n", 1, "hold takes a whole number of frames"),
            ("dolly inf\n", 1, "'inf' is not a finite number"),
            ("wait 1\nanimate nan\n", 2, "'nan' is not a finite number"),
            ("animate\n", 1, "'animate' takes 1 argument, not 0"),
        ] {
            let (n, message) = parse(text).unwrap_err();
            assert_eq!(n, line, "{text:?}: {message}");
            assert!(message.contains(problem), "{text:?}: {message}");
        }
    }
}
